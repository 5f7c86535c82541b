# Two commands do everything (README): `make run` and `make test`.
# Both create the virtual environment in .venv on first use.
VENV   ?= .venv
PY     := $(VENV)/bin/python
PRESET ?= presets/p4-cy-steel.toml
OUT    ?= runs/$(basename $(notdir $(PRESET))).zarr

.PHONY: run test bench

$(VENV)/.installed: pyproject.toml
	python3 -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $@

run: $(VENV)/.installed
	mkdir -p runs
	$(VENV)/bin/taimill run $(PRESET) --out $(OUT) --overwrite

# pytest exits 5 when it collects nothing: that is not a failure of the suite.
test: $(VENV)/.installed
	$(PY) -m pytest -q $(PYTEST_ARGS); rc=$$?; if [ $$rc -eq 5 ]; then rc=0; fi; exit $$rc

bench: $(VENV)/.installed
	$(PY) scripts/bench.py
