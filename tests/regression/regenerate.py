"""Rewrite values.json from the current code (see cases.py for when to do this).

    python -m tests.regression.regenerate
"""

from __future__ import annotations

import json
from pathlib import Path

import dampersim
from dampersim.fileio import write_text_atomic
from tests.regression.cases import CASES, linear_frequencies, run_case

VALUES = Path(__file__).with_name("values.json")


def main() -> None:
    data = {
        "generated_by": "python -m tests.regression.regenerate",
        "dampersim_version": dampersim.__version__,
        "time_step_s": dampersim.default_parameters().solver.time_step,
        "linear_frequencies_hz": linear_frequencies(),
        "cases": {name: run_case(name) for name in CASES},
    }
    write_text_atomic(VALUES, json.dumps(data, indent=1) + "\n")
    print(f"wrote {VALUES.name}: {len(data['cases'])} cases")


if __name__ == "__main__":
    main()
