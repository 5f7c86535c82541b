"""The stream a run emits and its consumers: the sink protocol and in-memory sinks
(`sinks`), the zarr run store (`run`) and the sweep store (`sweep`). No Taichi, no
analysis: columns come from `taimill.schema`."""
