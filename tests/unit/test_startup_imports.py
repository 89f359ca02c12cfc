"""What importing the dashboard loads: scipy stays out until an order track or a diagnosis runs.

Every server start, job process and test server imports ``app``; scipy.signal (which pulls in
scipy.stats) added about 1.1 s to it (`python -X importtime -c "import app"`: 3.2 to 3.5 s
with it, 2.0 to 2.3 s without, on one core of the 2-core test machine). The import runs in a
fresh interpreter, as a server start does.
"""

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: scipy subpackages the library imports only inside the functions that use them
LAZY = ("scipy.signal", "scipy.stats", "scipy.fft", "scipy.interpolate", "scipy.linalg", "scipy.special",
        "scipy.optimize")


def test_importing_the_app_loads_no_scipy_subpackage():
    code = ("import json, sys; import app; "
            f"print(json.dumps([m for m in {list(LAZY)!r} if m in sys.modules]))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    assert json.loads(out.stdout.strip().splitlines()[-1]) == []
