"""The one rule of what a strength does to a joint (docs/kgm/method.md §4.6, §6.4): every friction
angle set to a value with cohesion held (the critical friction angle's searches), and tanφ and c
divided by a factor F (strength reduction, the factor of safety's searches).

Mohr–Coulomb joints: φ → atan(tan(φ or the set angle)/F), c → c/F, the tensile strength kept.
Barton–Bandis joints: a set friction angle replaces the law (a Mohr–Coulomb joint at that angle);
a reduction divides tan φ(σn) at each contact's own stress, and c (docs/method/barton_bandis.md).
Bolts' passive capacities are divided by F like the joints' strength (docs/method/water_bolts.md).

`Strength` applies it to the joints of a scene (the DDA judgements' sub-models) and to the
contact arrays of a block system (`kgm.BlockSystem.with_strength`); the two keep their own
arithmetic (scalar and NumPy), as each always had.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace
from typing import Optional

import numpy as np


@dataclass(frozen=True, kw_only=True)
class Strength:
    """The strength of every joint in a judgement."""

    friction: Optional[float] = None
    """Friction angle given to every joint [degrees] (cohesion held), or None: the joints' own."""
    reduction: float = 1.0
    """Strength-reduction factor F: tanφ/F and c/F on every joint [-]."""

    def joint(self, joint):
        """A `ddatai.Joint` (or `ddatai.BartonBandis`) at this strength."""
        from ddatai.params import UnitWarning

        with warnings.catch_warnings():  # c/F of a joint checked when it was built: no unit slip
            warnings.simplefilter("ignore", UnitWarning)
            return self._reduced(joint)

    def _reduced(self, joint):
        from ddatai.params import BartonBandis, Joint

        if isinstance(joint, BartonBandis) and self.friction is None:
            # tan φ(σn)/F at each contact's own stress, c/F (docs/method/barton_bandis.md)
            return replace(joint, reduction=joint.reduction * self.reduction,
                           cohesion=joint.cohesion / self.reduction)
        phi = joint.friction if self.friction is None else float(self.friction)
        tan_phi = math.tan(math.radians(phi)) / self.reduction
        return Joint(friction=math.degrees(math.atan(tan_phi)), cohesion=joint.cohesion / self.reduction,
                     tensile=joint.tensile)

    def capacity(self, capacity: float) -> float:
        """A bolt's capacity at this strength [N]."""
        return capacity / self.reduction

    def contact_arrays(self, friction: np.ndarray, cohesion: np.ndarray, barton: Optional[np.ndarray]) -> dict:
        """A block system's contact friction [degrees], cohesion [Pa] and Barton–Bandis law
        (`kgm.BlockSystem.contact_barton`) at this strength, as fields of the system."""
        phi = friction if self.friction is None else np.full(len(friction), float(self.friction))
        tan_phi = np.tan(np.radians(phi)) / self.reduction
        if barton is not None:
            # a set friction angle replaces every law; a reduction divides tan φ(σn) too
            barton = None if self.friction is not None else barton * np.array([1, 1, 1, 1, self.reduction])
        return dict(contact_friction=np.degrees(np.arctan(tan_phi)), contact_cohesion=cohesion / self.reduction,
                    contact_barton=barton)
