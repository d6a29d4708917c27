# Two commands on a fresh machine: `make demo` and `make test`. Both bootstrap .venv from this repo's files.
# `make check` is the developer's loop: lint and the unit tier (tests/unit/, no process started, about a minute).
# `make native` compiles the step loop (railsim/native.py); demo, test and bench do it first.
# The interpreter .venv is made with, chosen only when .venv is made: the fastest build of python3's version on
# this machine (railsim/interpreter.py; `make PY=/path/to/python` chooses yourself, `make clean` drops .venv).
PY      ?= $$(python3 railsim/interpreter.py)
VENV    := .venv
BIN     := $(VENV)/bin
STAMP   := $(VENV)/.installed
SCENARIO ?= scenarios/chongqing_line3_peak.yaml
OUT     ?= out/demo
# pytest-xdist workers for `make test`: the machines have 2 cores (`make test WORKERS=0` runs in one process).
# worksteal: a worker that runs out of tests takes queued ones from the other, so the minutes-long tests of
# tests/golden/ and tests/long/ (collected first) do not all wait on one worker.
WORKERS ?= 2
PYTEST  := $(BIN)/python -m pytest -q -n $(WORKERS) --dist worksteal

.PHONY: venv pyc warm native demo lint check test test-fast format bench clean

$(STAMP): pyproject.toml constraints.txt
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	@echo "installing railsim and its dependencies into $(VENV) (log: $(VENV)/install.log)"
	@$(BIN)/python -m pip install --upgrade pip > $(VENV)/install.log 2>&1 || (cat $(VENV)/install.log; exit 1)
	@$(BIN)/python -m pip install -c constraints.txt -e '.[test,dask]' >> $(VENV)/install.log 2>&1 || (cat $(VENV)/install.log; exit 1)
	touch $(STAMP)

venv: $(STAMP)

# Byte-compile the repository's own modules once (quick when they are up to date). The suite starts hundreds of
# processes that import railsim; where PYTHONDONTWRITEBYTECODE is set (CI images often set it), none of them would
# write a .pyc, and each would compile every module from source again (about 0.3 s of CPU a process).
pyc: $(STAMP)
	$(BIN)/python -m compileall -q railsim controllers network tests benchmarks > /dev/null

# Compile numba's kernels into their on-disk cache once (tests/warm.py; a few seconds when they are cached): on a
# fresh clone the test processes would otherwise each compile the same kernels at once. The test targets run it
# beside the lint (make -j2), on the core the lint leaves idle.
warm: pyc
	$(BIN)/python -m tests.warm

# Compile the step loop's modules to C with mypyc into build/native/ (railsim/native.py; a few minutes of one core,
# nothing when they are up to date). Without a C compiler it says so and railsim runs interpreted.
native: $(STAMP)
	-@$(BIN)/python -m railsim.compile_core --if-stale

demo: $(STAMP) native
	$(BIN)/railsim network build chongqing_line3 --out $(OUT)/network
	$(BIN)/railsim run $(SCENARIO) --out $(OUT)

# Static checks, cheapest first (config in pyproject.toml: [tool.ruff], [tool.mypy], [tool.importlinter]).
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy
	$(BIN)/lint-imports --no-cache

# Test tiers by folder (tests/conftest.py): unit, sumo, golden, long. `make test` (CI) runs them all and prints
# the 25 slowest tests; `make test-fast` leaves out golden and long.
check: $(STAMP)
	$(MAKE) --no-print-directory -j2 lint warm
	$(PYTEST) tests/unit

test: $(STAMP)
	$(MAKE) --no-print-directory -j2 lint warm native
	$(PYTEST) --durations=25

test-fast: $(STAMP)
	$(MAKE) --no-print-directory -j2 lint warm native
	$(PYTEST) tests/unit tests/sumo

# Format the tree (`make test` checks it is formatted).
format: $(STAMP)
	$(BIN)/ruff check --fix .
	$(BIN)/ruff format .

bench: $(STAMP) native
	$(BIN)/python benchmarks/engine.py

clean:
	rm -rf $(VENV) out build *.egg-info
