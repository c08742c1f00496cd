"""Probabilistic wedge studies: Fisher-distributed joint orientations and distributed
properties, sampled by kgm's probabilistic machinery (`kgm.sample_variables`: Monte Carlo or
Latin hypercube, Gaussian-copula correlations) and judged all at once by the vectorised
evaluator (`kgm.wedges.batched`) — docs/kgm/wedge.md §5.

Two probabilities are reported, as SWedge does and as the literature asks (a wedge that does
not form cannot fail, and slivers give misleadingly low factors):

* P_f = failed / samples, over every sample;
* P(sliding | wedge) = failed / valid, valid = a wedge forms with at least ``min_volume``.

Variables are named after the inputs of `kgm.wedge`: ``joint1_dip``, ``joint1_dip_direction``,
``joint1_friction``, ``joint1_cohesion`` (``joint1_jrc``, ``joint1_jcs``,
``joint1_residual_friction`` for a Barton–Bandis joint), ``joint1_orientation`` (a `Fisher`:
the pole scattered about the mean orientation), the same for ``joint2`` and a basal
``joint3``; ``face_dip``, ``face_dip_direction``, ``upper_dip``, ``upper_dip_direction``,
``height``, ``density``, ``water_fill``, ``seismic_k``, ``crack_dip``, ``crack_dip_direction``,
``crack_distance``, ``bench_width``. Each maps to a frozen `scipy.stats` distribution or a number.
"""

from __future__ import annotations

import csv
import json
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping, Optional

import numpy as np

from ..kinds import Sampling
from ..studies.sampling import sample_variables
from . import batched
from .geometry import _finite, plane_normal

HEADER_MARK = "# kgm wedge study "
SCALARS = ("face_dip", "face_dip_direction", "upper_dip", "upper_dip_direction", "height", "density", "water_fill",
           "seismic_k", "crack_dip", "crack_dip_direction", "crack_distance", "bench_width")
JOINT_FIELDS = ("dip", "dip_direction", "friction", "cohesion", "jrc", "jcs", "residual_friction")


@dataclass(frozen=True)
class Fisher:
    """Fisher's distribution of a joint's pole about its mean orientation, concentration
    ``kappa`` K (> 0): the angle θ from the mean has P(θ' ≤ θ) = (1 − e^(K(cos θ − 1)))/(1 − e^(−2K)),
    its azimuth about the mean is uniform (Fisher 1953). K ≈ 140.2/θ₆₃² for θ₆₃ [degrees], the
    cone holding 63 % of the poles (θ95 ≈ 140/√K for the mean itself)."""

    kappa: float

    def __post_init__(self) -> None:
        if not (_finite(self.kappa) and self.kappa > 0):
            raise ValueError(f"Fisher.kappa (concentration K) must be > 0, got {self.kappa!r}")

    def ppf(self, u):
        """The angle θ [degrees] from the mean pole at probability ``u`` (inverse CDF)."""
        u = np.asarray(u, dtype=float)
        k = float(self.kappa)
        # cos θ = 1 + ln(1 − u(1 − e^(−2K)))/K, written to stay exact for large K
        cos = 1.0 + np.log1p(-u * -np.expm1(-2.0 * k)) / k
        return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


class _Uniform360:
    """The azimuth of a Fisher pole about its mean [degrees] (uniform)."""

    def ppf(self, u):
        return 360.0 * np.asarray(u, dtype=float)


def scatter(dip, dip_direction, angle, azimuth) -> tuple[np.ndarray, np.ndarray]:
    """Planes whose normals are those of (dip, dip direction) turned by ``angle`` towards the
    ``azimuth`` measured about the mean from its strike [degrees, arrays]; returns (dip, dip
    direction)."""
    n = plane_normal(dip, dip_direction)
    e1 = np.stack([np.cos(np.radians(dip_direction)), -np.sin(np.radians(dip_direction)),
                   np.zeros(np.shape(dip_direction))], axis=-1)            # strike: horizontal, ⟂ n
    e1 = np.broadcast_to(e1, n.shape)
    e2 = np.cross(n, e1)
    t, a = np.radians(angle)[..., None], np.radians(azimuth)[..., None]
    m = np.cos(t) * n + np.sin(t) * (np.cos(a) * e1 + np.sin(a) * e2)
    m = np.where(m[..., 2:3] < 0, -m, m)
    dip_out = np.degrees(np.arccos(np.clip(m[..., 2], -1.0, 1.0)))
    return dip_out, np.degrees(np.arctan2(m[..., 0], m[..., 1])) % 360.0


@dataclass(frozen=True, kw_only=True, eq=False)
class WedgeStudy:
    """Outcome of `wedge_study`."""

    n: int
    """Samples [-]."""
    pf: float
    """P_f: samples whose wedge forms (at least ``min_volume``) and has FS < 1, over all [-]."""
    p_sliding: float
    """P(sliding | wedge): failed over valid samples (nan without a valid one) [-]."""
    valid: int
    """Samples where a wedge of at least ``min_volume`` forms [-]."""
    table: np.ndarray
    """One row per sample (structured array): ``index``, the sampled variables, ``forms``,
    ``reason``, ``volume``, ``weight``, ``fs``, ``valid``, ``failed``, ``mode``, ``trend``, ``plunge``."""
    variables: tuple
    sampling: str
    seed: int
    min_volume: float
    wall_time: float = 0.0
    """Wall time of sampling and evaluation [s]."""
    resumed: int = 0
    """Samples read back from ``out`` instead of evaluated [-]."""

    @property
    def fs(self) -> np.ndarray:
        return self.table["fs"]

    def fs_quantiles(self, q=(0.05, 0.5, 0.95)) -> dict:
        """Quantiles of FS over the valid samples [-]."""
        f = self.table["fs"][self.table["valid"]]
        return {float(p): (float(np.quantile(f, p)) if len(f) else math.nan) for p in q}

    def reasons(self) -> dict:
        """Why no wedge formed: reason -> samples."""
        r = self.table["reason"]
        return {name: int(np.sum(r == name)) for name in sorted(set(r.tolist())) if name}

    def summary(self) -> str:
        rate = self.n / self.wall_time if self.wall_time > 0 else math.inf
        return (f"{self.n} samples ({self.sampling}, seed {self.seed}): P_f = {self.pf:.4f}, "
                f"P(sliding | wedge ≥ {self.min_volume:g} m³) = {self.p_sliding:.4f} over {self.valid} wedges; "
                f"{rate:,.0f} samples/s")

    def to_csv(self, path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "w", newline="") as fh:
            fh.write(HEADER_MARK + json.dumps(self._identity()) + "\n")
            w = csv.writer(fh)
            w.writerow(self.table.dtype.names)
            for row in self.table:
                w.writerow([repr(float(v)) if isinstance(v, (float, np.floating)) else
                            (int(v) if isinstance(v, (bool, np.bool_)) else v) for v in row.tolist()])
        return path

    def _identity(self) -> dict:
        return dict(n=self.n, seed=self.seed, sampling=self.sampling, variables=list(self.variables),
                    min_volume=self.min_volume)


def wedge_study(base, variables: Mapping, n: int, *, sampling: str = Sampling.MONTE_CARLO, seed: int = 0,
                correlation: Optional[Mapping] = None, min_volume: float = 0.0, out=None,
                workers: Optional[int] = None, client=None) -> WedgeStudy:
    """Probability of failure of a wedge with uncertain inputs (module docstring).

    ``base``: a `kgm.Wedge` (its inputs) or a mapping of `kgm.wedge` arguments; ``variables``:
    name -> distribution / number / `Fisher`; ``n`` samples drawn before any work from ``seed``
    (`kgm.sample_variables`, ``sampling`` 'monte-carlo' or 'latin-hypercube', ``correlation``
    of normal scores); all evaluated at once (`kgm.wedges.batched.evaluate`, ``workers``
    threads), or, with ``client`` (a ``dask.distributed.Client`` or a scheduler address), in
    chunks of ``CLUSTER_CHUNK`` samples on the cluster's workers (`ddatai.parallel.run`, as
    `kgm.probabilistic` runs there): the same table either way. ``out``: a CSV of every sample,
    read back instead of recomputed when it holds this very study.
    """
    inputs = dict(base.inputs if hasattr(base, "inputs") else base)
    sampling = str(getattr(sampling, "value", sampling))          # a kgm.kinds.Sampling or its name
    if not (_finite(min_volume) and min_volume >= 0):
        raise ValueError(f"min_volume must be a volume >= 0 m³, got {min_volume!r}")
    joints = inputs["joints"]
    known = set(SCALARS) | {f"joint{k + 1}_{f}" for k in range(len(joints)) for f in JOINT_FIELDS + ("orientation",)}
    expanded = {}
    for name, v in dict(variables).items():
        if name not in known:
            raise ValueError(f"wedge study: unknown variable {name!r}; known: {', '.join(sorted(known))}")
        if isinstance(v, Fisher):
            expanded[f"{name}_angle"], expanded[f"{name}_azimuth"] = v, _Uniform360()
        else:
            expanded[name] = v
    t0 = time.perf_counter()
    identity = dict(n=n, seed=seed, sampling=sampling, variables=list(expanded), min_volume=float(min_volume))
    if out is not None and Path(out).is_file():
        table = _read(out, identity)
        if table is not None:
            return _study(table, identity, time.perf_counter() - t0, resumed=n)
    samples = sample_variables(expanded, n, sampling=sampling, seed=seed, correlation=correlation)
    res = _evaluate(inputs, samples, n, workers, client)
    trend, plunge = _trend_plunge(res.sliding)
    valid = res.forms & (res.volume >= min_volume)
    columns = [("index", np.arange(n))] + [(k, np.asarray(v, float)) for k, v in samples.items()] + [
        ("forms", res.forms), ("reason", np.array(batched.REASONS, dtype=object)[res.reason].astype(str)),
        ("volume", res.volume), ("weight", res.weight), ("fs", res.fs), ("valid", valid),
        ("failed", valid & (res.fs < 1.0)), ("mode", np.array(batched.MODES, dtype=object)[res.mode].astype(str)),
        ("trend", trend), ("plunge", plunge)]
    table = np.rec.fromarrays([c for _, c in columns], names=[k for k, _ in columns])
    study = _study(np.asarray(table), identity, time.perf_counter() - t0)
    if out is not None:
        study.to_csv(out)
    return study


#: samples a task of a study on a Dask cluster
CLUSTER_CHUNK = 50_000


def _evaluate(inputs, samples, n, workers, client) -> "batched.BatchResult":
    if client is None:
        return batched.evaluate(**_batch_arguments(inputs, samples, n), workers=workers)
    from ddatai.parallel import run

    items = [(k, (inputs, {name: v[lo:lo + CLUSTER_CHUNK] for name, v in samples.items()}))
             for k, lo in enumerate(range(0, n, CLUSTER_CHUNK))]
    parts = dict(run(_evaluate_part, items, client=client, chunk=1))
    fields = batched.BatchResult.__dataclass_fields__
    return batched.BatchResult(**{f: np.concatenate([getattr(parts[k], f) for k in range(len(items))])
                                  for f in fields})


def _evaluate_part(item) -> "batched.BatchResult":
    """One chunk of a study on a cluster worker (top level: picklable)."""
    inputs, samples = item
    n = len(next(iter(samples.values()))) if samples else 0
    return batched.evaluate(**_batch_arguments(inputs, samples, n), workers=1)


def limit_state(base, *, min_volume: float = 0.0, workers: Optional[int] = None):
    """The wedge's factor of safety as a vectorised function of sampled variables, for
    samplings that choose their samples as they go (subset simulation, importance sampling):
    ``f(samples)`` takes a mapping name -> array (the names of `wedge_study`; a `Fisher` joint
    as ``jointK_orientation_angle`` and ``_azimuth``, degrees) and returns FS per sample, +inf
    where no wedge of at least ``min_volume`` forms (it cannot fail)."""
    inputs = dict(base.inputs if hasattr(base, "inputs") else base)

    def fs(samples: Mapping) -> np.ndarray:
        n = len(next(iter(samples.values()))) if samples else 1
        res = batched.evaluate(**_batch_arguments(inputs, dict(samples), n), workers=workers)
        return np.where(res.forms & (res.volume >= min_volume), res.fs, np.inf)

    return fs


def _study(table, identity, wall, resumed=0) -> WedgeStudy:
    n = identity["n"]
    valid = int(np.sum(table["valid"]))
    failed = int(np.sum(table["failed"]))
    return WedgeStudy(n=n, pf=failed / n, p_sliding=(failed / valid if valid else math.nan), valid=valid, table=table,
                      variables=tuple(identity["variables"]), sampling=identity["sampling"], seed=identity["seed"],
                      min_volume=identity["min_volume"], wall_time=wall, resumed=resumed)


def _trend_plunge(v):
    with np.errstate(invalid="ignore"):
        plunge = np.degrees(np.arcsin(np.clip(-v[:, 2], -1, 1)))
        trend = np.degrees(np.arctan2(v[:, 0], v[:, 1])) % 360.0
    return trend, plunge


def _batch_arguments(inputs: dict, samples: dict, n: int) -> dict:
    """`batched.evaluate` arguments: the base inputs, overridden by the sampled variables."""
    from ddatai.params import BartonBandis

    from .mechanics import seismic_load

    face, upper, joints = inputs["face"], inputs["upper"], inputs["joints"]
    get = lambda name, default: np.asarray(samples[name], float) if name in samples else default  # noqa: E731
    m = len(joints)
    cols = {f: [] for f in JOINT_FIELDS}
    for k, plane in enumerate(joints):
        law = plane.joint
        bb = isinstance(law, BartonBandis)
        dip = get(f"joint{k + 1}_dip", np.full(n, plane.dip))
        dd = get(f"joint{k + 1}_dip_direction", np.full(n, plane.dip_direction))
        if f"joint{k + 1}_orientation_angle" in samples:
            dip, dd = scatter(dip, dd, samples[f"joint{k + 1}_orientation_angle"],
                              samples[f"joint{k + 1}_orientation_azimuth"])
        cols["dip"].append(dip)
        cols["dip_direction"].append(dd)
        cols["friction"].append(get(f"joint{k + 1}_friction", np.full(n, law.friction)))
        cols["cohesion"].append(get(f"joint{k + 1}_cohesion", np.full(n, law.cohesion)))
        cols["jrc"].append(get(f"joint{k + 1}_jrc", np.full(n, law.jrc if bb else np.nan)))
        cols["jcs"].append(get(f"joint{k + 1}_jcs", np.full(n, law.jcs if bb else np.nan)))
        cols["residual_friction"].append(get(f"joint{k + 1}_residual_friction",
                                             np.full(n, law.residual_friction if bb else np.nan)))
    stack = {f: np.column_stack(v) for f, v in cols.items()}
    barton = None
    if any(isinstance(j.joint, BartonBandis) for j in joints):
        caps = np.array([j.joint.max_friction if isinstance(j.joint, BartonBandis) else np.nan for j in joints])
        red = np.array([j.joint.reduction if isinstance(j.joint, BartonBandis) else 1.0 for j in joints])
        barton = dict(jrc=stack["jrc"], jcs=stack["jcs"], residual=stack["residual_friction"],
                      cap=np.broadcast_to(caps, (n, m)), reduction=np.broadcast_to(red, (n, m)))
        # the residual angle is the friction a Barton–Bandis joint reports
        stack["friction"] = np.where(np.isnan(stack["jrc"]), stack["friction"], stack["residual_friction"])
    water = inputs.get("water")
    if water is not None and water.pressures is not None:
        raise ValueError("a wedge study takes Hoek & Bray's filled fissures (kgm.Water(fill=...)), "
                         "not custom pressures")
    seismic = seismic_load(inputs.get("seismic"))
    crack = inputs.get("tension_crack")
    if crack is not None and not hasattr(crack, "plane"):
        from .slope import TensionCrack

        crack = TensionCrack(*crack)
    active, passive = np.zeros(3), np.zeros(3)
    for b in inputs.get("bolts", ()):
        if b.kind == "active":
            active = active + b.vector
        else:
            passive = passive + b.vector
    for f in inputs.get("forces", ()):
        active = active + f.vector
    has_crack = crack is not None or "crack_distance" in samples
    if has_crack and crack is None:
        raise ValueError("crack_* variables need a tension crack in the base wedge")
    fill = get("water_fill", None if water is None else np.full(n, water.fill))
    k = get("seismic_k", None if seismic is None else np.full(n, seismic.k))
    return dict(face_dip=get("face_dip", face.dip), face_dip_direction=get("face_dip_direction", face.dip_direction),
                upper_dip=get("upper_dip", upper.dip), upper_dip_direction=get("upper_dip_direction", upper.dip_direction),
                height=get("height", float(inputs["height"])), joint_dip=stack["dip"],
                joint_dip_direction=stack["dip_direction"], friction=stack["friction"], cohesion=stack["cohesion"],
                barton=barton, density=get("density", float(inputs.get("density", 2600.0))),
                gravity=float(inputs.get("gravity", 9.81)), water_fill=fill,
                water_density=(water.density if water is not None else 1000.0), seismic_k=k,
                seismic_trend=None if seismic is None else seismic.trend,
                seismic_plunge=0.0 if seismic is None else seismic.plunge, active_force=active, passive_force=passive,
                crack_dip=get("crack_dip", crack.plane.dip) if has_crack else None,
                crack_dip_direction=get("crack_dip_direction", crack.plane.dip_direction) if has_crack else None,
                crack_distance=get("crack_distance", crack.distance) if has_crack else None,
                bench_width=get("bench_width", inputs.get("bench_width")),
                slope_length=inputs.get("slope_length"), height_reference=inputs.get("height_reference", "joint1"))


def _read(path, identity) -> Optional[np.ndarray]:
    """The table of a CSV written by the same study, or None."""
    with open(path, newline="") as fh:
        head = fh.readline()
        if not head.startswith(HEADER_MARK) or json.loads(head[len(HEADER_MARK):]) != identity:
            return None
        rows = list(csv.reader(fh))
    names, rows = rows[0], rows[1:]
    if len(rows) != identity["n"]:
        return None
    text = {"reason", "mode"}
    boolean = {"forms", "valid", "failed"}
    cols = []
    for j, name in enumerate(names):
        col = [r[j] for r in rows]
        if name in text:
            cols.append(np.array(col, dtype=str))
        elif name in boolean:
            cols.append(np.array([c in ("1", "True") for c in col]))
        elif name == "index":
            cols.append(np.array(col, dtype=np.int64))
        else:
            cols.append(np.array(col, dtype=float))
    return np.asarray(np.rec.fromarrays(cols, names=names))
