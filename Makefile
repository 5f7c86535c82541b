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

.PHONY: run test test-fresh test-forge bench

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

# A fresh machine (CI runs it after `test`): the tests that read what the kernel cache and
# taimill's compile records hold, with HOME and Taichi's cache folder empty (a run of the
# suite on a machine that had compiled before hid a KeyError a fresh one raised).
FRESH_TESTS := tests/test_messages.py
test-fresh: $(VENV)/.installed-test
	rm -rf .fresh && mkdir -p .fresh/home
	HOME=$(CURDIR)/.fresh/home TI_OFFLINE_CACHE_FILE_PATH=$(CURDIR)/.fresh/cache/ticache $(PY) -m pytest -q -p no:cacheprovider $(FRESH_TESTS)
	rm -rf .fresh

# The second door (CI runs it after `test`): the golden runs, the neighbour tests and the
# door's own tests on the fork taichi-forge, which Python 3.14 gets instead of taichi, so
# that a fork release that changes a bit is caught. Its environment sees the first one's
# packages (a .pth file) and adds only the fork (the `forge` extra, ≈ 170 MB); the same
# interpreter builds it. TAIMILL_TAICHI makes the door take the fork though taichi is there.
FORGE_VENV  ?= .venv-forge
FORGE_TESTS := tests/test_golden.py tests/test_neighbours.py tests/test_layers.py \
	tests/test_runs.py::test_the_door_passes_taichis_variables_and_settings_through \
	tests/test_runs.py::test_a_held_taichi_cache_lock_leaves_stderr_clean \
	tests/test_runs.py::test_init_taichi_removes_an_old_lock_in_the_cache_folder_it_uses

$(FORGE_VENV)/.installed: pyproject.toml $(VENV)/.installed-test
	$(PY) -m venv $(FORGE_VENV)
	$(FORGE_VENV)/bin/python -c 'import sys, sysconfig; open(sysconfig.get_paths()["purelib"] + "/taimill-base.pth", "w").write("import site; site.addsitedir(%r)\n" % sys.argv[1])' "$$($(PY) -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
	$(FORGE_VENV)/bin/python -m pip install --quiet -e '.[forge]'
	touch $@

test-forge: $(FORGE_VENV)/.installed
	TAIMILL_TAICHI=taichi-forge $(FORGE_VENV)/bin/python -c 'from taimill.physics import ti; assert ti.IMPLEMENTATION.name == "taichi-forge"; print("the second door:", ti.describe())'
	TAIMILL_TAICHI=taichi-forge $(FORGE_VENV)/bin/python -m pytest -q -n auto --dist loadfile $(FORGE_TESTS)

bench: $(VENV)/.installed-run
	$(PY) scripts/bench.py
