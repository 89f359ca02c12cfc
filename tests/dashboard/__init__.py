"""Dashboard tests without a browser (views, callbacks, HTTP)."""
