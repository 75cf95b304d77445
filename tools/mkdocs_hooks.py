"""MkDocs hooks of the manual (mkdocs.yml).

- The one version source, shown in the site's name and wherever a page writes ``{{ version }}``.
- The changelog page is CHANGELOG.md itself.
- ``<!-- members: shprobe.pkg -->`` on an API page stands for one ``::: shprobe.pkg.NAME`` per
  name of that module's ``__all__`` that the page does not already show, in ``__all__`` order:
  a page lists its main job first by hand and can never miss a public name added later. Each
  public object is rendered once, on its package's page, so every cross-reference has one target.
- ``<!-- public-names -->`` is the table of ``import shprobe``'s names (``_EXPORTS``), each
  linked to where its package's page documents it.
- The code is highlighted by Pygments at build time (``pymdownx.highlight``); its style sheet is
  written into the site here, so the manual loads nothing from another host.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
PYGMENTS_CSS = "css/pygments.css"


def version() -> str:
    text = (SRC / "shprobe" / "_version.py").read_text(encoding="utf-8")
    return re.search(r'__version__ = "([^"]+)"', text).group(1)


def on_config(config, **kwargs):
    config.site_name = f"shprobe {version()}"
    if PYGMENTS_CSS not in config.extra_css:
        config.extra_css.append(PYGMENTS_CSS)
    return config


def on_page_markdown(markdown: str, page, config, files, **kwargs) -> str:
    if page.file.src_uri == "changelog.md":
        # CHANGELOG.md's links to docs/x.md read as x.md inside the manual
        text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
        return re.sub(r"docs/([a-z_-]+\.md)", r"\1", text)
    markdown = markdown.replace("<!-- public-names -->", public_names_table())
    markdown = re.sub(r"<!-- members: ([\w.]+)(?: level=(\d))? -->",
                      lambda m: members(m.group(1), markdown, int(m.group(2) or 2)), markdown)
    return markdown.replace("{{ version }}", version())


def on_post_build(config, **kwargs) -> None:
    from pygments.formatters import HtmlFormatter

    site = Path(config.site_dir)
    out = site / PYGMENTS_CSS
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(HtmlFormatter(style="default").get_style_defs(".highlight"), encoding="utf-8")
    index = site / "search" / "search_index.json"
    if index.exists():
        # The search plugin's page script runs lunr in a web worker that fetches the index
        # as JSON: both are refused to a page opened from file://. The index as a script and a
        # main-thread search load from <script> tags, which file:// allows.
        (site / "search" / "search_index.js").write_text(
            "var shprobeSearchIndex = " + index.read_text(encoding="utf-8") + ";\n",
            encoding="utf-8")
        (site / "search" / "main.js").write_text(SEARCH_JS, encoding="utf-8")


SEARCH_JS = """// The manual's search, on the page's own thread (file:// or a server).
(function () {
  var index = null, docs = {}, minLength = 3;
  function url(path) { return base_url.replace(/\\/$/, "") + "/" + path; }
  function load(src, done) {
    var s = document.createElement("script");
    s.src = url(src); s.onload = done;
    s.onerror = function () { console.error("search: could not load " + src); };
    document.head.appendChild(s);
  }
  function escapeHtml(v) {
    return v.replace(/&/g, "&amp;").replace(/"/g, "&quot;").replace(/</g, "&lt;")
      .replace(/>/g, "&gt;");
  }
  function show(results) {
    var box = document.getElementById("mkdocs-search-results");
    if (!box) return;
    box.innerHTML = "";
    if (!results.length) {
      box.insertAdjacentHTML("beforeend", "<p>" +
        (box.getAttribute("data-no-results-text") || "No results found") + "</p>");
    }
    results.forEach(function (d) {
      box.insertAdjacentHTML("beforeend", '<article><h3><a href="' + url(d.location) + '">' +
        escapeHtml(d.title) + "</a></h3><p>" + escapeHtml(d.text.substring(0, 200)) +
        "</p></article>");
    });
  }
  function search() {
    var q = document.getElementById("mkdocs-search-query").value;
    if (!index || q.length < minLength) { show([]); return; }
    var hits;
    try { hits = index.search(q); } catch (e) { hits = []; }
    show(hits.map(function (h) { return docs[h.ref]; }));
  }
  function ready() {
    var data = window.shprobeSearchIndex;
    if (data.config && data.config.separator) {
      lunr.tokenizer.separator = new RegExp(data.config.separator);
    }
    if (data.config && data.config.min_search_length) minLength = data.config.min_search_length;
    index = lunr(function () {
      this.field("title"); this.field("text"); this.ref("location");
      for (var i = 0; i < data.docs.length; i++) {
        this.add(data.docs[i]); docs[data.docs[i].location] = data.docs[i];
      }
    });
    var input = document.getElementById("mkdocs-search-query");
    if (input) {
      input.addEventListener("keyup", search);
      input.setAttribute("data-search-ready", "1");
      var m = /[?&]q=([^&]*)/.exec(window.location.search);
      if (m) { input.value = decodeURIComponent(m[1].replace(/\\+/g, "%20")); search(); }
      if (input.value) search();
    }
  }
  load("search/lunr.js", function () { load("search/search_index.js", ready); });
})();
"""


def module_file(module: str) -> Path:
    base = SRC / Path(*module.split("."))
    return base / "__init__.py" if base.is_dir() else base.with_suffix(".py")


def module_all(module: str) -> list[str]:
    """The module's ``__all__`` (a literal list), read from the source without importing it;
    without one, the documented functions and classes it defines whose names do not start
    with ``_``."""
    tree = ast.parse(module_file(module).read_text(encoding="utf-8"))
    for node in tree.body:
        target = node.targets[0] if isinstance(node, ast.Assign) else getattr(node, "target", None)
        if getattr(target, "id", "") == "__all__":
            return list(ast.literal_eval(node.value))
    return [n.name for n in tree.body
            if isinstance(n, ast.FunctionDef | ast.ClassDef) and not n.name.startswith("_")
            and ast.get_docstring(n)]


def members(module: str, page: str, level: int) -> str:
    shown = set(re.findall(r"^::: ([\w.]+)\s*$", page, flags=re.M))
    out = []
    for name in module_all(module):
        target = f"{module}.{name}"
        if (SRC / Path(*target.split("."))).is_dir() or module_file(target).is_file():
            # a name that is also a submodule's (lighting.irradiance, scene.render): the
            # reference would resolve it to the module, so the object is named where it lives
            target = f"{target}.{name}"
        if target not in shown:
            out.append(f"::: {target}\n    options:\n      heading_level: {level}\n")
    return "\n".join(out)


def exports() -> dict[str, str]:
    """shprobe's public names → the module that defines them (``_EXPORTS`` of __init__.py)."""
    tree = ast.parse((SRC / "shprobe" / "__init__.py").read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.AnnAssign) and getattr(node.target, "id", "") == "_EXPORTS":
            return ast.literal_eval(node.value)
    raise RuntimeError("src/shprobe/__init__.py has no _EXPORTS")


def public_names_table() -> str:
    """One row per public name, linked (an autorefs cross-reference, so a name documented
    nowhere fails the strict build) to its documentation on its package's page."""
    rows = ["| name | defined in |", "|---|---|"]
    for name, mod in sorted(exports().items(), key=lambda kv: rank(kv[1])):
        rows.append(f"| [`shprobe.{name}`][shprobe.{mod}.{name}] | `shprobe.{mod}` |")
    return "\n".join(rows)


#: the order of the public names' table: the main jobs first, the SH helpers after
ORDER = ("probes.env", "lighting", "scene", "prt", "hbasis", "grids", "splats", "fitting",
         "report", "batch", "probes", "sh", "errors")


def rank(module: str) -> int:
    return next((i for i, m in enumerate(ORDER) if module == m or module.startswith(m + ".")),
                len(ORDER))
