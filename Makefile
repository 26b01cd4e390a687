# The two commands a user needs on a fresh clone: `make demo` and `make test`.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: install demo test test-slow lint bench clean

install: $(STAMP)

$(STAMP): pyproject.toml Makefile
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,gpu]'
	# REBOUNDx (the forces' cross-checks) builds from source against the installed REBOUND.
	$(BIN)/python -m pip install --quiet wheel setuptools
	$(BIN)/python -m pip install --quiet --no-build-isolation 'reboundx==5.1.0'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/orbitsim demo -o demo-report

# The suite runs on every core (pytest-xdist; TEST_WORKERS=0 for one process) and ends with its
# slowest tests. Workers share Numba's on-disk cache: each kernel is written under a temporary name
# and renamed into place, so a kernel compiled by two workers at once is stored whole. Each test file
# goes to one worker (--dist loadfile): a file's tests use the same kernels, and split over two
# workers with an empty cache both compiled them (16% more CPU on the forces + WH files, measured).
# A case whose kernels are a family of their own (tens of seconds to compile on an empty cache: the map's
# lanes, TRACE with events, IAS15 with forces, each further scheme of a cross-product) is marked slow and
# runs in `make test-slow` (tests/suite_split.py); CI runs both.
TEST_WORKERS ?= auto

# The package's bytecode is compiled first (0.4 s once; pip does it for a wheel, not for an editable
# install): where PYTHONDONTWRITEBYTECODE is set, as on the machines this suite is developed on, every
# process the tests start would otherwise compile orbitsim's modules again (~0.4 s for all of them;
# tests/cli: 26.0 -> 24.2 CPU-s). A stale file is only ignored, never run.
test: $(STAMP)
	$(BIN)/ruff check orbitsim tests benchmarks
	$(BIN)/python -m compileall -q orbitsim > /dev/null
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile --durations=20

test-slow: $(STAMP)
	$(BIN)/python -m compileall -q orbitsim > /dev/null
	$(BIN)/python -m pytest -q -m slow

lint: $(STAMP)
	$(BIN)/ruff check orbitsim tests benchmarks

bench: $(STAMP)
	$(BIN)/orbitsim bench full -o benchmarks/results

clean:
	rm -rf $(VENV) demo-report .pytest_cache
	find orbitsim tests benchmarks -name __pycache__ -type d -prune -exec rm -rf {} +
