# Two commands do everything (README): `make run` and `make test`.
# Both create the virtual environment in .venv on first use. `make run` installs only
# what running needs; `make test` adds the test extra (pytest, the snapshot plugin and
# rerun's catalog extra with pandas and datafusion, ≈ 200 MB) on top. Each install has
# its own stamp, so either target works first, alone or after the other.
VENV   ?= .venv
PY     := $(VENV)/bin/python
PRESET ?= presets/p4-cy-steel.toml
OUT    ?= runs/$(basename $(notdir $(PRESET))).zarr

.PHONY: run test bench

$(PY):
	python3 -m venv $(VENV)
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
