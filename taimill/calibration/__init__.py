"""Calibration and validation of contact parameters (thesis §2.1.1, §2.2.1, §2.3):
drop-test data, the fit of d / c_max / e, sensitivity and oblique-impact tables, their
figures and pair files. NumPy only: the experiments themselves are run by
`taimill.calibration.runs`, imported inside the functions that need it."""
