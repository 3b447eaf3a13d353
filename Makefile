# Quick start: `make run` launches the app, `make test` runs the whole suite.
PYTHON ?= python3
VENV := .venv
# pytest-xdist processes for `make test` (each file runs whole in one; 0: no workers). Three
# on two cores: with two the suite waited a third of its time (windows drawing, child
# processes starting: 824 s of CPU in 564 s); measured, three took 9:03 and 9:23 of pytest
# against 9:23 for two with 19 tests fewer: no clear gain yet, and no harm; four took 9:37
# against 9:08 for three (session 21: the suite uses about 1.4 of the two cores either way)
TEST_WORKERS ?= 3
# a worker that crashes ends the run, naming the test (--max-worker-restart 0): with
# --dist loadfile, xdist 3.8's replacement worker is never given work and the run hangs
# (pytest-xdist issues 784 and 1323, fixed after 3.8.0)
# test-quick's files mostly wait (GUI frames, child processes): a third worker fills the
# cores while the others wait (3 min 07 s with two workers, 2 min 56 s with three)
QUICK_WORKERS ?= 3
BIN := $(VENV)/bin

.PHONY: run test test-quick test-under-load lint bench clean

$(BIN)/activate:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --upgrade pip

$(VENV)/.installed: pyproject.toml | $(BIN)/activate
	$(BIN)/pip install -e .
	touch $@

$(VENV)/.installed-test: pyproject.toml | $(BIN)/activate
	$(BIN)/pip install -e ".[test]"
	touch $@ $(VENV)/.installed

# the integrators' stepping loops and the chaos maps' default loops, compiled once into
# numba's cache (python main.py warm); again only when their source changes
WARM_SOURCES := systems/integrators/kernels.py systems/integrators/codes.py \
	systems/codegen.py systems/chaos/map_kernels.py
$(VENV)/.warm: $(VENV)/.installed $(WARM_SOURCES)
	$(BIN)/python main.py warm
	touch $@

run: $(VENV)/.installed $(VENV)/.warm
	$(BIN)/python main.py

test: $(VENV)/.installed-test
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/lint-imports
	$(BIN)/python -m pytest -n $(TEST_WORKERS) --dist loadfile --max-worker-restart 0 --durations=25

# everyday work: the suite without its model-based, soak and slow tests (the session
# copies the drivers `warm` compiled instead of compiling its own: tests/conftest.py)
test-quick: $(VENV)/.installed-test $(VENV)/.warm
	$(BIN)/python -m pytest -n $(QUICK_WORKERS) --dist loadfile --max-worker-restart 0 -m "not slow and not soak" -q

# the whole suite beside two busy loops, as on a shared machine (run before a release)
test-under-load: $(VENV)/.installed-test
	$(BIN)/python tests/under_load.py --busy 2 -- $(MAKE) test

bench: $(VENV)/.installed-test
	$(BIN)/pip install -e ".[bench]"
	$(BIN)/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) build *.egg-info
