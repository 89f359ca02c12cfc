"""Property-based fuzzing of the URL-state parser of every page, the range parser and the
re-parsing of stored/posted job states: only the documented error types, bounded time
and bounded allocation.

Documented behaviour: ``parse_query`` and ``reparse_state`` never raise on any query
(every refusal is a notice); ``parse_values`` / ``count_values`` raise only InputError.
Budgets: each example within 0.5 s (hypothesis ``deadline``; a parse is milliseconds,
and expanding an uncounted range list would take seconds) and 10 MB of Python
allocations (a 400-value grid is kilobytes; an uncounted 100 000-value item is 10 MB of
floats on its own). ``max_examples`` keeps the file well under 20 s.
"""

from __future__ import annotations

import tracemalloc

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dampersim.errors import InputError
from dampersim.sweeps.grid import count_values, parse_values
from dampersim.views.state import MAX_SWEEP_POINTS, PAGES, parse_query, reparse_state

MEM = 10e6
FUZZ = settings(max_examples=60, deadline=500, suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])

numbers = st.one_of(st.integers(-10**30, 10**30), st.floats(allow_nan=True, allow_infinity=True),
                    st.sampled_from(["1e-8", "1e400", "-0", "nan", "inf", "0x10", "1_000", "", " ", "1e308"]))
range_items = st.builds(lambda a, b, c: f"{a}:{b}:{c}", numbers, numbers, numbers)
range_text = st.lists(st.one_of(range_items, numbers.map(str), st.text(max_size=12)), min_size=0, max_size=30).map(",".join)
values = st.one_of(numbers, range_text, st.text(max_size=80), st.booleans(),
                   st.lists(st.text(max_size=10), max_size=3), st.just(None), st.just({"a": 1}))
param_keys = st.sampled_from(["solver.time_step", "solver.duration", "solver.outer_segments", "solver.inner_segments",
                              "solver.output_sample_rate", "solver.segment_sample_rate", "inertias.primary", "set",
                              "friction.enabled", "motor.mode", "no.such.name"])


def bounded_alloc(fn, *args):
    tracemalloc.start()
    try:
        out = fn(*args)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < MEM, f"{peak / 1e6:.1f} MB"
    return out


def query_strategy(page):
    keys = st.sampled_from([f.key for f in PAGES[page]] + ["unknown"])
    return st.dictionaries(st.one_of(keys, param_keys), values, max_size=8)


@pytest.mark.parametrize("page", ["explorer", "segments", "colourmap", "maps", "hysteresis"])
def test_parse_query_never_raises_and_stays_bounded(page, cache_dir):
    @FUZZ
    @given(query=query_strategy(page))
    def check(query):
        state, notices = bounded_alloc(parse_query, page, query)
        assert set(f.key for f in PAGES[page]) <= set(state)
        assert all(isinstance(n["text"], str) and "Traceback" not in n["text"] for n in notices)
        if page in ("colourmap", "maps"):
            n = count_values(state["speeds"], "speeds", "rpm")
            if page == "maps":
                n *= count_values(state["torques"], "torques", "N m")
            assert n <= MAX_SWEEP_POINTS

    check()


@pytest.mark.parametrize("page", ["colourmap", "maps", "hysteresis"])
def test_reparse_of_posted_job_states(page, cache_dir):
    @FUZZ
    @given(raw=st.one_of(query_strategy(page), values,
                         st.fixed_dictionaries({"params": st.one_of(values, st.dictionaries(param_keys, values, max_size=4))})))
    def check(raw):
        state, notices = bounded_alloc(reparse_state, page, raw)
        assert isinstance(notices, list) and "params" in state

    check()


@FUZZ
@given(text=st.one_of(range_text, st.text(max_size=200), numbers))
def test_parse_values_raises_only_input_error(text):
    try:
        n = count_values(text)
    except InputError:
        n = None
    try:
        out = bounded_alloc(parse_values, text, "--speeds", "rpm", MAX_SWEEP_POINTS)
    except InputError as exc:
        assert str(exc)  # a message naming the option and what is accepted
        return
    assert n is not None and len(out) == n <= MAX_SWEEP_POINTS


def test_counting_comes_before_expansion():
    """The property the fuzzing relies on, without hypothesis: 25 items of 100 000 values
    are refused from their numbers, with the count, allocating next to nothing."""
    text = ",".join(["300:6000:0.05701"] * 25)
    with pytest.raises(InputError, match="expands to 2499575 values; at most 400"):
        bounded_alloc(parse_values, text, "speeds", "rpm", MAX_SWEEP_POINTS)
    with pytest.raises(InputError, match="more than 1e15"):
        parse_values("0:1e300:1e-300", "speeds", "rpm")
