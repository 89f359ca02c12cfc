# dampersim developer entry points. Needs only python3 (>= 3.11) and GNU make;
# `make test` also installs Debian's chromium + chromium-driver when run as root.

PY ?= python3
VENV ?= .venv

VENV_PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
TEST_CACHE := $(CURDIR)/.test-cache
PYTEST_ARGS ?=
# Test files to run first, alone on the machine, before the two lanes below; empty by default,
# so the strict identification tests run in their lane on one core beside the rest, which keeps
# the whole suite shortest. STRICT_TESTS=tests/discrepancy/test_identification.py gives their
# diagnoses both cores (shorter for them, about a third longer in all: docs/discrepancy.md, Known
# limits). PYTEST_ARGS goes to both runs: give it options, not paths (scripts/run-tests.sh says
# how the two exit statuses combine).
STRICT_TESTS ?=
# Two processes: modules that only compute run beside the rest of the suite
# (tests/conftest.py, APART); PYTEST_XDIST= runs everything in one process.
PYTEST_XDIST ?= -n 2

# numba's cache=True writes here, so it works in a fresh clone / read-only tree.
export NUMBA_CACHE_DIR ?= $(CURDIR)/.numba-cache

.PHONY: all venv run test bench clean

all: test

venv: $(STAMP)

# Re-installs only when pyproject.toml is newer than the stamp.
$(STAMP): pyproject.toml
	test -x $(VENV_PY) || $(PY) -m venv $(VENV)
	$(VENV_PY) -m pip install --upgrade pip
	$(VENV_PY) -m pip install -e '.[test]'
	touch $@

run: venv
	$(VENV_PY) app.py --host 127.0.0.1 --port 8050

# Each `make test` starts with a cold result cache (its two pytest runs share it).
test: export DAMPERSIM_CACHE_DIR := $(TEST_CACHE)
test: venv
	rm -rf $(TEST_CACHE)
	mkdir -p $(TEST_CACHE)
	bash scripts/ensure-chromium.sh
	$(VENV)/bin/lint-imports --no-cache
	PY=$(VENV_PY) STRICT_TESTS="$(STRICT_TESTS)" PYTEST_XDIST="$(PYTEST_XDIST)" bash scripts/run-tests.sh $(PYTEST_ARGS)

bench: venv
	@set -e; found=0; \
	for f in bench/*.py; do \
	  [ -e "$$f" ] || continue; found=1; \
	  echo "== $$f"; \
	  $(VENV_PY) "$$f"; \
	done; \
	[ $$found = 1 ] || echo "no bench/*.py scripts found"

clean:
	rm -rf $(VENV) .numba-cache .test-cache .pytest_cache build dist *.egg-info
	find . -path ./.git -prune -o -type d -name __pycache__ -prune -exec rm -rf {} +
	find cache -mindepth 1 -maxdepth 1 ! -name .gitkeep ! -name README -exec rm -rf {} +
