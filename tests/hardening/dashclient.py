"""A small HTTP client that opens dashboard links the way the browser's Dash renderer does,
for load tests and benchmarks that need many sessions without many browsers.

It speaks Dash's callback protocol over plain HTTP: the page's index (for the signed
``end_id`` and the session cookie), ``/_dash-dependencies``, the pages callback that
returns the page layout for a path and query, then a chosen callback with the input
values read from that layout (pattern-matching ``ALL`` inputs included) and, for a
background callback, the polls with ``cacheKey``/``job`` until its result arrives. Only
the standard library is used, so a benchmark can run hundreds of sessions in threads.
"""

from __future__ import annotations

import http.cookiejar
import json
import re
import time
import urllib.error
import urllib.parse
import urllib.request

_CONFIG = re.compile(r'<script id="_dash-config" type="application/json">(.*?)</script>', re.S)


def _walk(node, out):
    """Collect {id-key: props} of every component with an id in a layout tree."""
    if isinstance(node, list):
        for item in node:
            _walk(item, out)
    elif isinstance(node, dict):
        if "props" in node and "type" in node:
            props = node["props"] or {}
            if "id" in props:
                out[_id_key(props["id"])] = (props["id"], props)
            for value in props.values():
                _walk(value, out)
        else:
            for value in node.values():
                _walk(value, out)


def _id_key(cid) -> str:
    return json.dumps(cid, sort_keys=True, separators=(",", ":")) if isinstance(cid, dict) else str(cid)


def _parse_dep_id(text: str):
    """A dependency id as /_dash-dependencies writes it: "name" or a JSON pattern."""
    if text.startswith("{"):
        return json.loads(text)
    return text


def _matches(pattern: dict, cid) -> bool:
    if not isinstance(cid, dict) or set(cid) != set(pattern):
        return False
    for k, v in pattern.items():
        if v == ["ALL"] or v == ["MATCH"] or v == ["ALLSMALLER"]:
            continue
        if cid[k] != v:
            return False
    return True


class Response:
    """Status, wall time [s] and decoded JSON (or text) of one request."""

    def __init__(self, status, seconds, body, text):
        self.status, self.seconds, self.json, self.text = status, seconds, body, text


class DashSession:
    """One browser session (own cookie jar) on a running dashboard at ``base`` (an
    http://host:port URL)."""

    def __init__(self, base: str, timeout: float = 30.0, host_header: str | None = None):
        self.base = base.rstrip("/")
        self.timeout = timeout
        self.host_header = host_header
        self.jar = http.cookiejar.CookieJar()
        self.opener = urllib.request.build_opener(urllib.request.HTTPCookieProcessor(self.jar))
        self.end_id = None
        self.deps = None
        self.layout = {}
        self.path = "/"
        self.search = ""

    # ----------------------------------------------------------------- transport
    def request(self, path: str, body=None, query: dict | None = None) -> Response:
        url = self.base + path
        if query:
            url += ("&" if "?" in url else "?") + urllib.parse.urlencode(query)
        data = None if body is None else json.dumps(body).encode()
        req = urllib.request.Request(url, data=data, method="POST" if body is not None else "GET")
        if body is not None:
            req.add_header("Content-Type", "application/json")
        if self.host_header:
            req.add_header("Host", self.host_header)
        t0 = time.perf_counter()
        try:
            with self.opener.open(req, timeout=self.timeout) as resp:
                raw, status = resp.read(), resp.status
        except urllib.error.HTTPError as exc:
            raw, status = exc.read(), exc.code
        seconds = time.perf_counter() - t0
        text = raw.decode("utf-8", "replace")
        try:
            parsed = json.loads(text) if text[:1] in "{[" else None
        except ValueError:
            parsed = None
        return Response(status, seconds, parsed, text)

    # ----------------------------------------------------------------- pages
    def open(self, link: str) -> Response:
        """Load a page link ("/colourmap?speeds=…"): index, dependencies, page layout."""
        parts = urllib.parse.urlsplit(link)
        self.path, self.search = parts.path or "/", ("?" + parts.query) if parts.query else ""
        index = self.request(link)
        if index.status != 200:
            return index
        m = _CONFIG.search(index.text)
        self.end_id = json.loads(m.group(1)).get("end_id") if m else None
        if self.deps is None:
            self.deps = self.request("/_dash-dependencies").json or []
        self.request("/_dash-layout")
        out = self.call_outputs("_pages_content.children", {
            "_pages_location.pathname": self.path, "_pages_location.search": self.search})
        self.layout = {}
        if out.json:
            _walk(out.json.get("response", {}), self.layout)
        return out

    def dependency(self, output_contains: str) -> dict:
        for dep in self.deps or ():
            if output_contains in dep["output"]:
                return dep
        raise KeyError(f"no callback with output {output_contains!r}")

    def _value(self, spec: dict, overrides: dict):
        cid, prop = _parse_dep_id(spec["id"]), spec["property"]
        if isinstance(cid, dict):
            items = [{"id": real, "property": prop, "value": props.get(prop)}
                     for real, props in self.layout.values() if _matches(cid, real)]
            return items
        key = f"{cid}.{prop}"
        if key in overrides:
            value = overrides[key]
        else:
            value = self.layout.get(_id_key(cid), (cid, {}))[1].get(prop)
        return {"id": cid, "property": prop, "value": value}

    def _body(self, dep: dict, overrides: dict, changed=None) -> dict:
        inputs = [self._value(s, overrides) for s in dep["inputs"]]
        state = [self._value(s, overrides) for s in dep.get("state", [])]
        outputs_text = dep["output"]
        if outputs_text.startswith(".."):
            outs = [o for o in outputs_text.strip(".").split("...")]
        else:
            outs = [outputs_text]
        outputs = []
        for o in outs:
            cid, _, prop = o.split("@")[0].rpartition(".")
            outputs.append({"id": cid, "property": prop})
        if changed is None:  # a page's first call: every input counts as changed
            changed = []
            for item in inputs:
                for one in item if isinstance(item, list) else [item]:
                    changed.append(f"{_id_key(one['id'])}.{one['property']}")
        return {"output": outputs_text, "outputs": outputs if len(outputs) > 1 else outputs[0],
                "inputs": inputs, "state": state, "changedPropIds": changed}

    def call_outputs(self, output_contains: str, overrides: dict | None = None, changed=None,
                     query: dict | None = None) -> Response:
        """POST the callback whose output contains ``output_contains``, inputs read from the
        layout (``overrides``: {"id.prop": value})."""
        dep = self.dependency(output_contains)
        body = self._body(dep, overrides or {}, changed)
        return self.request("/_dash-update-component", body, {**self._end(), **(query or {})})

    def _end(self) -> dict:
        """The renderer sends the page load's signed end id with every callback request."""
        return {"endId": self.end_id} if self.end_id else {}

    def run_background(self, output_contains: str, overrides: dict, poll_s: float = 0.3,
                       deadline_s: float = 600.0) -> tuple:
        """Start a background callback and poll it until it answers; returns
        (final response, number of polls). A response without ``cacheKey`` (a cached
        result or a refusal) is returned at once."""
        dep = self.dependency(output_contains)
        body = self._body(dep, overrides)
        first = self.request("/_dash-update-component", body, self._end() or None)
        if not first.json or "cacheKey" not in first.json:
            return first, 0
        handles = {"cacheKey": first.json["cacheKey"], "job": first.json["job"], **self._end()}
        polls, t0 = 0, time.monotonic()
        while time.monotonic() - t0 < deadline_s:
            time.sleep(poll_s)
            polls += 1
            resp = self.request("/_dash-update-component", body, handles)
            if resp.status == 204:
                return resp, polls
            if resp.status != 200:
                return resp, polls
            if resp.json and resp.json.get("response"):
                return resp, polls
        return Response(0, deadline_s, None, "deadline"), polls


__all__ = ["DashSession", "Response"]
