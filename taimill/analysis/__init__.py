"""Analysis of runs, NumPy only: runs on any store, also one made on another machine.
Modules: `theory` (analytic landmarks), `events` (stress energy and power estimators),
`sampled` (the output-sampled estimator), `spatial` (g(r), contact and wear maps),
`regime` (motion regime), `summary` (the run summary, for a run, a stored run and the
TUI's window), `sweep` (statistics over sweep points), `run` (everything about one
stored run)."""
