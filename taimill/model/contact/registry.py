"""The sub-models by kind and name, and the named normal laws (compositions).

| law            | spring | damping g(u)             | source                        |
|----------------|--------|--------------------------|-------------------------------|
| adams-impact   | hertz  | adams-step: step(u/d)    | MSC.Adams IMPACT, eqs 2.20/3.2 |
| kelvin-voigt   | linear | viscous: 1               | eq 2.13, k* of eq 2.17        |
| hertz-damper   | hertz  | viscous: 1               | eq 2.18 (Dubowsky)            |
| hunt-crossley  | hertz  | hunt-crossley: k uⁿ      | eq 2.19, Hunt & Crossley 1975 |
| hertz-mindlin  | hertz  | tsuji: √(m_e n k u^(n-1)) | Tsuji 1992 / EDEM: constant e |

A new sub-model is its own module (NumPy here; its Taichi twin in `taimill.physics`,
as `taimill.physics.rolling_epsd2`), one line in its kind's registry below and one in
its kind's table of `taimill.physics.laws`, under the same name. The LIGGGHTS export
writes it once it has a row in `taimill.bridge.contact_map`'s tables, and refuses it
until then.
"""

from __future__ import annotations

from taimill.model.contact import damping, rolling, rolling_epsd2, springs, tangential, tangential_history
from taimill.model.contact.model import ContactModel, NormalModel


def _by_name(*models) -> dict:
    return {m.name: m for m in models}


SPRINGS = _by_name(springs.HERTZ, springs.LINEAR, springs.POWER)
DAMPINGS = _by_name(damping.STEP, damping.VISCOUS, damping.HUNT_CROSSLEY, damping.TSUJI)
TANGENTIAL = _by_name(tangential.REGULARISED_COULOMB, tangential_history.HISTORY)
ROLLING = _by_name(rolling.CONSTANT_TORQUE, rolling_epsd2.EPSD2)

LAWS = _by_name(
    NormalModel("adams-impact", springs.HERTZ, damping.STEP),
    NormalModel("kelvin-voigt", springs.LINEAR, damping.VISCOUS, constant_e=True),
    NormalModel("hertz-damper", springs.HERTZ, damping.VISCOUS),
    NormalModel("hunt-crossley", springs.HERTZ, damping.HUNT_CROSSLEY),
    NormalModel("hertz-mindlin", springs.HERTZ, damping.TSUJI, constant_e=True),
)
NAMES = tuple(LAWS)  #: the normal laws' names, as users type them
CONSTANT_E_LAWS = tuple(name for name, law in LAWS.items() if law.constant_e)
DEFAULT_TANGENTIAL = tangential.REGULARISED_COULOMB.name
DEFAULT_ROLLING = rolling.CONSTANT_TORQUE.name


def law_by_name(name: str) -> NormalModel:
    """The normal law called `name` (one of NAMES)."""
    return LAWS[name]


def contact_model(normal: NormalModel, tangential_name: str = DEFAULT_TANGENTIAL,
                  rolling_name: str = DEFAULT_ROLLING) -> ContactModel:
    """The composition a contact type runs with."""
    return ContactModel(normal, TANGENTIAL[tangential_name], ROLLING[rolling_name])
