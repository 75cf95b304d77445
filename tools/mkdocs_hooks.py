"""MkDocs hooks of the manual (mkdocs.yml): the one version source, shown in the site's name
and wherever a page writes ``{{ version }}``; the changelog page is CHANGELOG.md itself."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def version() -> str:
    text = (ROOT / "src" / "shprobe" / "_version.py").read_text(encoding="utf-8")
    return re.search(r'__version__ = "([^"]+)"', text).group(1)


def on_config(config, **kwargs):
    config.site_name = f"shprobe {version()}"
    return config


def on_page_markdown(markdown: str, page, config, files, **kwargs) -> str:
    if page.file.src_uri == "changelog.md":
        # CHANGELOG.md's links to docs/x.md read as x.md inside the manual
        text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
        return re.sub(r"docs/([a-z_]+\.md)", r"\1", text)
    markdown = markdown.replace("<!-- public-names-table -->", public_names_table())
    markdown = markdown.replace("<!-- public-names -->", public_names_reference())
    return markdown.replace("{{ version }}", version())


def exports() -> dict[str, str]:
    """shprobe's public names → the module that defines them (``_EXPORTS`` of __init__.py)."""
    import ast

    tree = ast.parse((ROOT / "src" / "shprobe" / "__init__.py").read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.AnnAssign) and getattr(node.target, "id", "") == "_EXPORTS":
            return ast.literal_eval(node.value)
    raise RuntimeError("src/shprobe/__init__.py has no _EXPORTS")


def public_names_table() -> str:
    rows = ["| name | defined in |", "|---|---|"]
    for name, mod in sorted(exports().items(), key=lambda kv: kv[0].lower()):
        rows.append(f"| [`shprobe.{name}`](shprobe.md#shprobe.{mod}.{name}) | `shprobe.{mod}` |")
    return "\n".join(rows)


def public_names_reference() -> str:
    out = []
    for name, mod in exports().items():
        out.append(f"::: shprobe.{mod}.{name}\n    options:\n      heading_level: 2\n"
                   f"      show_root_full_path: true\n")
    return "\n".join(out)
