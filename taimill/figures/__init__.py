"""Every matplotlib figure of taimill: run reports (`report`), sweep curves (`sweep`),
jar drawings (`jars`) and calibration plots (`calibration`). Figures read NumPy data
from the analysis and the stores; nothing below this package imports matplotlib."""
