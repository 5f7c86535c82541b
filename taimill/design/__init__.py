"""The jar designer (`taimill design`, docs/designer.md): parametric jar families,
the maker's constraints, an Optuna study evaluated on the sweep machinery, and its
report."""
