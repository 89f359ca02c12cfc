#!/usr/bin/env bash
# The test run of `make test`: the files of STRICT_TESTS, when given, first and alone on the
# machine (for the strict identification tests: so that their diagnoses have both cores), then
# the rest of the suite in the two lanes of tests/conftest.py (APART).
#
#   PY=python STRICT_TESTS="tests/a.py" PYTEST_XDIST="-n 2" bash scripts/run-tests.sh [pytest options]
#
# PY: the interpreter that runs pytest. STRICT_TESTS: the test files run first (empty: no first
# run, they stay in the lanes). PYTEST_XDIST: the second run's own options. The arguments go to
# both runs: give options, not paths (a path would run in both).
#
# Exit status: the first failing run's. Status 5 (pytest selected no test, e.g. a -k that
# matches only the other run's tests) is a failure only when both runs selected nothing. After
# a failing first run, -x or --exitfirst among the arguments skips the second.
set -u

py=${PY:?"PY: the python that runs pytest"}
strict=${STRICT_TESTS-}
first=5  # "selected nothing" when there is no first run
if [ -n "$strict" ]; then
  echo "== strict identification tests, alone: $strict"
  # shellcheck disable=SC2086  # one word per test file
  "$py" -m pytest $strict "$@"
  first=$?
fi

failed() { [ "$1" -ne 0 ] && [ "$1" -ne 5 ]; }

rest=skipped
stop_first=no
for arg in "$@"; do
  case $arg in -x | --exitfirst) stop_first=yes ;; esac
done
if failed "$first" && [ "$stop_first" = yes ]; then
  echo "== the rest of the suite: not run (the strict tests failed and -x asks to stop)"
else
  ignores=()
  for f in $strict; do ignores+=("--ignore=$f"); done
  echo "== the rest of the suite"
  # shellcheck disable=SC2086  # PYTEST_XDIST holds several options
  "$py" -m pytest ${PYTEST_XDIST-} "${ignores[@]}" "$@"
  rest=$?
fi

if [ -n "$strict" ]; then
  echo "== exit status: strict tests $first, the rest $rest"
fi
if failed "$first"; then exit "$first"; fi
# here the second run ran: it is skipped only after a failing first run
if failed "$rest"; then exit "$rest"; fi
if [ "$first" -eq 5 ] && [ "$rest" -eq 5 ]; then exit 5; fi
exit 0
