"""From collisions to milling outcome (docs/outcome.md): the specific energy dose of a
run's powder (`dose`), a condition's spectra and powder (`condition`), the outcome
models with their equations and sources (`models`) and their fit to measured points
with confidence intervals and an identifiability check (`fit`)."""
