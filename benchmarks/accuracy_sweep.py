"""The accuracy benchmark's sweep (``benchmarks/accuracy.py``): the parameter settings (the
defaults, then one field changed at a time) and one timed run of a case at a setting."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Optional

import ddatai as dd
from benchmarks.accuracy_cases import Case


# ----------------------------------------------------------------------------- sweeps
@dataclass(frozen=True)
class Config:
    """One parameter setting: the defaults, or the defaults with one field changed."""

    group: str
    label: str
    overrides: dict


DEFAULT_LABEL = "defaults"
CONTACT_GROUPS = ("penalty", "state", "open", "convergence")
WRONG_ANSWER_ERROR = 0.5
"""An error this large is a wrong answer (the block did not move, did not topple): such runs
are listed and drawn but kept off the best curve."""


def sweep_configs(quick: bool) -> list[Config]:
    if quick:
        return [Config("defaults", DEFAULT_LABEL, {}), Config("dt", "dt = 0.02 s", {"dt": 0.02})]
    configs = [Config("defaults", DEFAULT_LABEL, {})]
    configs += [Config("dt", f"dt = {v:g} s", {"dt": v}) for v in (0.02, 0.01, 0.005, 0.002, 0.001, 0.0005)]
    configs += [Config("dt_max", f"auto, dt_max = {v:g} s", {"dt_max": v})
                for v in (0.05, 0.02, 0.005, 0.002, 0.001)]
    configs += [Config("penalty", f"p = {v:g} E", {"penalty_ratio": v})
                for v in (5.0, 10.0, 20.0, 100.0, 500.0, 1000.0)]
    configs += [Config("state", f"state tol {v:g}", {"oc_state_tolerance": v})
                for v in (1e-5, 1e-4, 1e-2)]
    configs += [Config("start", "sudden gravity", {"initial_equilibrium": False})]
    # the strict open-close test of earlier versions (Coulomb within 1e-6 of each contact's
    # strength) against the default (1e-3 of the load carried; docs/method/dda.md §4.3)
    configs += [Config("convergence", "strict convergence", {"oc_force_reference": "strength",
                                                             "oc_force_tolerance": 1e-6})]
    configs += [Config("open", f"open tol {v:g} w0", {"open_tolerance": v})
                for v in (1e-14, 1e-12, 1e-11, 1e-10)]  # larger values are rejected: they act
    #                                           as tension and shear allowances (docs/guide/accuracy.md)
    return configs


@dataclass
class Run:
    case: str
    config: Config
    error: float
    wall: float
    cpu: float
    steps: int
    oc_mean: float
    dt_cuts: int
    note: str


def applies(case: Case, config: Config) -> bool:
    return case.has_contacts or config.group not in CONTACT_GROUPS


def case_params(case: Case, config: Config) -> Optional["dd.Params"]:
    """None (the library's defaults, as a user would call it) unless the case or the config
    sets a field."""
    fields = {**case.base_params, **config.overrides}
    return dd.Params(**fields) if fields else None


def run_case(case: Case, config: Config) -> Run:
    """Build the scene (untimed), time `dd.simulate` only, measure the error."""
    scene, measure = case.build()
    params = case_params(case, config)
    wall0, cpu0 = time.perf_counter(), time.process_time()
    try:
        res = dd.simulate(scene, params=params, duration=case.duration, record_every=case.record_every)
        failure = None
    except dd.SimulationError as err:
        res, failure = err.results, f"diverged ({err.cause}) at t = {err.time:.3g} s"
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    steps = res.steps if res is not None else None
    n = len(steps) if steps is not None else 0
    oc = float(steps["oc_iterations"].mean()) if n else math.nan
    cuts = int(steps["dt_cuts"].sum()) if n else 0
    if failure:
        return Run(case.key, config, math.nan, wall, cpu, n, oc, cuts, failure)
    error, note = measure(res)
    return Run(case.key, config, float(error), wall, cpu, n, oc, cuts, note)


def warm_up(cases: list[Case]) -> None:
    """Compile every Taichi kernel the cases use (contacts, loads, ground motion) untimed."""
    for case in cases:
        scene, _ = case.build()
        dd.simulate(scene, params=case_params(case, Config("defaults", DEFAULT_LABEL, {})),
                    steps=3, record_every=10 ** 9)
