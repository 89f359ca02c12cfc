"""Write small example rig recordings in every supported format into a folder.

Two recordings from synthetic signals with non-standard channel names and units
(``Trq_In`` [kN m], ``Torque_Output`` [N m] at 2 kHz; ``n_In`` [rpm], ``Speed_Out``
[rad/s] at 500 Hz), each as MDF4, TDMS, MAT v5, MAT v7.3 and CSV:

- ``testpoint.*``: 2 s at 1500 rpm and 200 N m with order 2 torque content;
- ``long_run.*``: 27 s of speed/torque plateaus with settling transients and a slow
  torque ramp (-200 to 300 N m), order 2 content throughout.

    python scripts/make_rig_examples.py OUT_FOLDER

The folder is created when missing; files of the same names are replaced.
"""

from __future__ import annotations

import argparse
import os
import sys

from dampersim.errors import InputError
from dampersim.rigdata.examples import WRITERS, demo_channels, long_recording_channels

NAMES = {"mdf4": "{}.mf4", "tdms": "{}.tdms", "mat5": "{}.mat", "mat73": "{}_v73.mat", "csv": "{}.csv"}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", help="output folder")
    args = ap.parse_args(argv)
    os.makedirs(args.folder, exist_ok=True)
    recordings = {"testpoint": demo_channels(duration_s=2.0), "long_run": long_recording_channels()}
    try:
        for stem, channels in recordings.items():
            for fmt, writer in WRITERS.items():
                path = writer(os.path.join(args.folder, NAMES[fmt].format(stem)), channels)
                print(f"{fmt:6s} {os.path.getsize(path) / 1e6:7.2f} MB  {path}")
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
