"""Validate an RO-Crate with roc-validator, offline: run with the Python of ``.venv/tools/rocrate``.

    python validate_rocrate.py CRATE CACHE [SEVERITY]

roc-validator fetches the RO-Crate JSON-LD context (``https://w3id.org/ro/crate/1.2/context``) through its
HTTP cache; a test machine has no network. The context is put into that cache from ro-crate-py's packaged
copy (``rocrate/data/ro-crate.jsonld``, the 1.3 context, whose terms include every 1.2 term), then the
validator runs in its ``--offline`` mode against the ``ro-crate-1.2`` profile and prints its JSON report.
"""

from __future__ import annotations

import io
import json
import subprocess
import sys
from pathlib import Path

import requests_cache
import rocrate
from requests.adapters import HTTPAdapter
from urllib3.response import HTTPResponse

CONTEXT_URL = "https://w3id.org/ro/crate/1.2/context"


class PackagedContext(HTTPAdapter):
    """Answers every request with ro-crate-py's copy of the RO-Crate context."""

    def __init__(self, body: bytes) -> None:
        super().__init__()
        self.body = body

    def send(self, request, **kwargs):  # noqa: ANN001, ANN003, ANN201 - requests' adapter interface
        raw = HTTPResponse(body=io.BytesIO(self.body), headers={"Content-Type": "application/ld+json"}, status=200,
                           preload_content=False, request_url=request.url)
        return self.build_response(request, raw)


def warm(cache: str) -> None:
    context = json.loads((Path(rocrate.__file__).parent / "data" / "ro-crate.jsonld").read_text(encoding="utf-8"))
    session = requests_cache.CachedSession(cache_name=cache, backend="sqlite", expire_after=-1)
    session.mount("https://w3id.org/", PackagedContext(json.dumps({"@context": context["@context"]}).encode()))
    answer = session.get(CONTEXT_URL, headers={"Accept": "application/ld+json, application/json"})
    answer.raise_for_status()


def main(crate: str, cache: str, severity: str = "REQUIRED") -> int:
    warm(cache)
    validator = Path(sys.executable).with_name("rocrate-validator")
    done = subprocess.run([str(validator), "-y", "--disable-color", "validate", "--offline", "--cache-path", cache,
                           "-p", "ro-crate-1.2", "--requirement-severity", severity, "--output-format", "json",
                           crate], capture_output=True, text=True)
    text = done.stdout
    print(text[text.find("{"):] if "{" in text else json.dumps({"error": done.stderr[-2000:] or text[-2000:]}))
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:]))
