"""CLI command: ``shprobe lightmap shader`` — the GLSL / HLSL / WGSL functions that shade with
a lightmap's coefficient textures at the normal-map normal (library:
`shprobe.lightmaps.shaders.lightmap_shader`). Joins the ``lightmap`` group."""

from __future__ import annotations

import click

from ..errors import ShprobeError
from .common import force_option
from .lightmap import lightmap

__all__ = ["shader_cmd"]


@lightmap.command("shader")
@click.argument("lightmap_file", metavar="[OUT.glb]", required=False,
                type=click.Path(dir_okay=False))
@click.option("--encoding", "encodings", multiple=True,
              type=click.Choice(["plain", "hl2", "sh4", "sh9", "h4", "h6"]),
              help="An encoding (repeatable); default: the file's, else all six.")
@click.option("--lang", type=click.Choice(["glsl", "hlsl", "wgsl"]), default="glsl",
              show_default=True, help="Shading language.")
@click.option("-o", "--output", default="-", show_default=True,
              help="Output file ('-': standard output).")
@force_option
def shader_cmd(lightmap_file, encodings, lang, output, force):
    """Shader functions that evaluate lightmap encodings from their coefficient textures
    with the normal-map normal (Habel & Wimmer 2010 eq. 15); given a lightmap .glb, for its
    encoding and texture packing."""
    from ..lightmaps import format as fmt
    from ..lightmaps.shaders import lightmap_shader

    layouts = None
    names = list(encodings)
    if lightmap_file is not None:
        doc, _ = fmt.read_glb(lightmap_file)
        ext = doc.get("extensions", {}).get(fmt.EXTENSION)
        if not isinstance(ext, dict) or "encoding" not in ext or "textures" not in ext:
            raise ShprobeError(f"has no {fmt.EXTENSION} extension: not a shprobe lightmap",
                               lightmap_file)
        stored = fmt.check_encoding(ext["encoding"])
        if names and names != [stored]:
            raise ShprobeError(f"the file stores {stored}; --encoding {', '.join(names)} "
                               "does not match it (omit --encoding)", lightmap_file)
        names = [stored]
        try:
            layouts = {stored: [[None if ic is None else (int(ic[0]), int(ic[1]))
                                 for ic in t["components"]] for t in ext["textures"]]}
        except (KeyError, TypeError, ValueError, IndexError):
            raise ShprobeError(f"its {fmt.EXTENSION} textures are malformed",
                               lightmap_file) from None
    text = lightmap_shader(names or list(fmt.ENCODINGS), lang, layouts)
    if output == "-":
        click.echo(text, nl=False)
        return
    from ..files import atomic_output, check_output_path
    from .output import wrote

    check_output_path(output, force)
    with atomic_output(output, force) as tmp:
        tmp.write_text(text)
    wrote(output, f"{lang}, {', '.join(names or fmt.ENCODINGS)}")
