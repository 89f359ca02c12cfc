"""Hardening tier: hostile links, forms, uploads and server faults.

Every case asserts a wall-time and a memory budget of its own (see each test), and that no
response carries a traceback or an absolute server path.
"""

from hypothesis import settings

# Property tests draw the same examples on every run (a failure is reproducible and CI
# cannot turn red by chance); no example database is written into the checkout.
settings.register_profile("dampersim", derandomize=True, database=None)
settings.load_profile("dampersim")
