"""Two build-time fixes of the documentation site (``hooks:`` in mkdocs.yml; kept out of the pages by
``exclude_docs``).

Sphinx roles in docstrings. The docstrings are numpy style and cite other objects with Sphinx roles
(``:func:`serve```, ``:class:`~features.prepared.PreparedScan```), which Markdown does not know: mkdocstrings
renders them as the role's name followed by inline code, ``:func:<code>serve</code>``. :func:`on_page_content`
keeps the inline code and drops the role, as Sphinx shows it: ``~pkg.mod.name`` as ``name`` only, and an
explicit title (``title <target>``) as the title. A role inside a code block is left as it stands.

Search from disk. A browser refuses to start a web worker from a page opened from disk (``file://``), and
the theme's search runs in one. The theme's ``offline`` plugin (mkdocs.yml) turns the directory URLs off
and writes the search index as a script, but takes the worker's stand-in from unpkg.com when the page opens:
no search on a machine without network. :func:`on_config` puts :data:`FILE_WORKER` in its place, a
stand-in written by :func:`on_files` into the site, which runs the worker's script in a hidden frame of the
page. Over HTTP it does nothing and the browser's own worker runs.
"""

from __future__ import annotations

import re

from mkdocs.plugins import event_priority
from mkdocs.structure.files import File

ROLE = re.compile(r":(?:py:)?(?:func|class|data|meth|mod|attr|exc|obj|const):<code>(?P<target>[^<]*)</code>")
TITLED = re.compile(r"(?P<title>.*?)\s*&lt;[^<]*&gt;", re.S)

FILE_WORKER = "assets/javascripts/file-worker.js"
FILE_WORKER_SOURCE = """\
// The search worker of a page opened from disk (file://), where the browser starts no web worker: its script
// runs in a hidden frame of the page, and messages pass between the two as a worker's would (docs/hooks.py).
if (location.protocol === "file:") {
  window.Worker = class extends EventTarget {
    constructor(url) {
      super();
      this.frame = document.createElement("iframe");
      this.frame.hidden = true;
      document.body.appendChild(this.frame);
      const scope = this.frame.contentWindow;
      scope.postMessage = (data) => {
        const message = new MessageEvent("message", { data });
        this.dispatchEvent(message);
        if (this.onmessage) this.onmessage(message);
      };
      this.ready = new Promise((resolve, reject) => {
        const script = scope.document.createElement("script");
        script.onload = resolve;
        script.onerror = reject;
        script.src = url;
        scope.document.head.appendChild(script);
      });
    }
    postMessage(data) {
      this.ready.then(() => this.frame.contentWindow.dispatchEvent(new MessageEvent("message", { data })));
    }
    terminate() {
      this.frame.remove();
    }
  };
}
"""


def _inline_code(match: re.Match[str]) -> str:
    target = match["target"]
    titled = TITLED.fullmatch(target)
    if titled:
        target = titled["title"]
    elif target.startswith("~"):
        target = target.rsplit(".", 1)[-1].lstrip("~")
    return f"<code>{target}</code>"


def on_page_content(html: str, **_) -> str:
    """The page's HTML with every Sphinx role of its docstrings as inline code (before the search index and
    the cross-references are made from it)."""
    return ROLE.sub(_inline_code, html)


@event_priority(-100)  # after the offline plugin has added its stand-in
def on_config(config, **_):
    polyfills = [p for p in config.extra.get("polyfills", []) if "iframe-worker" not in str(p)]
    config.extra["polyfills"] = [*polyfills, FILE_WORKER]
    return config


def on_files(files, config, **_):
    files.append(File.generated(config, FILE_WORKER, content=FILE_WORKER_SOURCE))
    return files

