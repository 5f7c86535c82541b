"""Input texts several test modules start from (no taimill import: NumPy-only tests use it)."""

# A valid preset: the CY jar, 12 steel balls, 1 s; tests edit one line of it.
GOOD_PRESET = """\
jar = "CY"
pair = "steel-steel"
plate_rpm = 200
ratio = -2.6
duration = 1.0
analysis_start = 0.5
dt = "auto"
seed = 1

[balls]
count = 12
material = "steel-c1020"
radius_mm = 6
"""
