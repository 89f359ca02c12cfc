"""Dashboard pages: one module per view (layout and callbacks only)."""
