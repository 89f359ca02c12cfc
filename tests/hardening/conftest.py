"""Hardening tier: hostile links, forms, uploads and server faults.

Every case asserts a wall-time and a memory budget of its own (see each test), and that no
response carries a traceback or an absolute server path.
"""
