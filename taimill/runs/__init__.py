"""Running mills: one preset run streaming to sinks (`simulation`), the live mill the
TUI drives (`live`), and sweeps with their local and dask executors (`sweep`,
`executors`). Built on the launcher of `taimill.physics.runner`."""
