"""Contact models composed of sub-models, NumPy side (the LAMMPS GRANULAR pattern):

    contact = normal spring + damping + tangential + rolling

Each sub-model is a small frozen dataclass with its coefficients' meaning and its
force as a pure NumPy function (the twin of a Taichi function registered under the
same name in `taimill.physics.laws`, some in a module of their own such as
`taimill.physics.tangential_history`), registered by name in one registry per kind
(`registry`). A run's kernels are compiled for the sub-models it uses: nothing in
the inner loop tests a model's name or id.

The thesis' normal "laws" (adams-impact, kelvin-voigt, hertz-damper, hunt-crossley,
hertz-mindlin) are named compositions of a spring and a damping (`registry.LAWS`).
"""

from taimill.model.contact.model import ContactModel, NormalModel

__all__ = ["ContactModel", "NormalModel"]
