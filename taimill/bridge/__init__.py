"""Bridges to other DEM codes: a preset exported as a LIGGGHTS case (`liggghts`, the
jar as a closed STL from `mesh`) and LIGGGHTS dumps imported back as a taimill run
store (`dumps`). NumPy only; LIGGGHTS itself is never imported, only its files."""
