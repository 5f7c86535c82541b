"""Analysis of stored runs (SPEC §5). NumPy only: runs on any store, also one made on
another machine. Modules: `theory` (analytic landmarks), `events` (stress energy and
power estimators), `spatial` (g(r), contact and wear maps), `regime` (motion regime),
`report` (figures)."""
