# Two commands do everything (README): `make run` and `make test`.
# Both create the virtual environment in .venv on first use. `make run` installs only
# what running needs; `make test` adds the test extra (pytest, the snapshot plugin and
# rerun's catalog extra with pandas and datafusion, ≈ 200 MB) on top. Each install has
# its own stamp, so either target works first, alone or after the other.
VENV   ?= .venv
PY     := $(VENV)/bin/python
PRESET ?= presets/p4-cy-steel.toml
OUT    ?= runs/$(basename $(notdir $(PRESET))).zarr

# Python 3.10-3.14: taichi 1.7.4 (upstream's last release) has wheels for CPython up to 3.13,
# and on 3.14 pyproject.toml installs the maintained fork taichi-forge instead
# (docs/platform.md). python3 builds the environment if it is one of these, else the first
# of python3.14 … python3.10 that runs; with none, the check below says what to do
OK_PY  := import sys; sys.exit(not (3, 10) <= sys.version_info[:2] <= (3, 14))
PYTHON ?= $(or $(shell for p in python3 python3.14 python3.13 python3.12 python3.11 python3.10; do $$p -c '$(OK_PY)' >/dev/null 2>&1 && { echo $$p; break; }; done),python3)

.PHONY: run test bench

$(PY):
	@$(PYTHON) -c 'import sys; v = sys.version_info[:2]; sys.exit(0 if (3, 10) <= v <= (3, 14) else "taimill needs Python 3.10 to 3.14 (neither taichi nor taichi-forge has wheels for %d.%d); install one and give it: make run PYTHON=python3.12" % v)'
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip

$(VENV)/.installed-run: pyproject.toml | $(PY)
	$(PY) -m pip install --quiet -e .
	touch $@

$(VENV)/.installed-test: pyproject.toml | $(PY)
	$(PY) -m pip install --quiet -e '.[test]'
	touch $@

run: $(VENV)/.installed-run
	mkdir -p runs
	$(VENV)/bin/taimill run $(PRESET) --out $(OUT) --overwrite

# pytest exits 5 when it collects nothing: that is not a failure of the suite.
test: $(VENV)/.installed-test
	$(PY) -m pytest -q -n auto --dist loadfile $(PYTEST_ARGS); rc=$$?; if [ $$rc -eq 5 ]; then rc=0; fi; exit $$rc

bench: $(VENV)/.installed-run
	$(PY) scripts/bench.py
