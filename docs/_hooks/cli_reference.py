"""mkdocs hook: the command-line reference, generated from the Typer app.

A page holding the line `<!-- cli-reference -->` gets, in its place, every command of
`diffpegasus` (groups walked recursively): its help text, its usage line and its
arguments and options (by help panel when the command has panels) with what `--help`
says of each. Nothing is written by hand, so the page follows the commands.
"""

import re


MARKER = "<!-- cli-reference -->"


def _paragraphs(text: str | None) -> str:
    """Help text as markdown: a paragraph's lines joined (docstrings wrap them),
    paragraphs and bulleted lines kept, Click's `\\b` markers dropped."""
    if not text:
        return ""
    out = []
    for block in re.split(r"\n\s*\n", text.strip()):
        lines = [line.strip() for line in block.splitlines()]
        lines = [line for line in lines if line and line != "\b"]
        if any(line.startswith(("- ", "* ")) for line in lines):
            out.append("\n".join(lines))
        else:
            out.append(" ".join(lines))
    return "\n\n".join(out)


def _cell(text: str) -> str:
    text = _paragraphs(text).replace("\n\n", "<br>").replace("\n", "<br>")
    return text.replace("|", "\\|")


def _row(param, ctx) -> tuple[str, str]:
    record = param.get_help_record(ctx)
    if record is None:  # an argument without help
        names, help_text = param.name.upper(), ""
    else:
        names, help_text = record
    names = " ".join(
        f"`{part}`" if part.startswith("-") else part for part in names.split(" ")
    )
    names = names.replace("<", "&lt;").replace(">", "&gt;").replace("|", "\\|")
    return names, _cell(help_text.replace("  [", " [") if help_text else "")


def _command(cmd, ctx, path: list[str], level: int) -> list[str]:
    name = " ".join(path)
    out = [f"{'#' * level} `{name}`", ""]
    if body := _paragraphs(cmd.help):
        out += [body, ""]
    usage = " ".join(cmd.collect_usage_pieces(ctx))
    out += ["```text", f"{name} {usage}".rstrip(), "```", ""]
    panels: dict[str, list[tuple[str, str]]] = {}
    for p in cmd.get_params(ctx):
        if getattr(p, "hidden", False) or "--help" in getattr(p, "opts", ()):
            continue
        kind = "Arguments" if p.param_type_name == "argument" else "Options"
        panel = getattr(p, "rich_help_panel", None) or kind
        panels.setdefault(panel, []).append(_row(p, ctx))
    for panel, rows in panels.items():
        if len(panels) > 1 or panel not in ("Options", "Arguments"):
            out += [f"**{panel}**", ""]
        out += ["| argument or option | meaning |", "|---|---|"]
        out += [f"| {names} | {help_text} |" for names, help_text in rows]
        out.append("")
    if hasattr(cmd, "list_commands"):
        for sub in cmd.list_commands(ctx):
            child = cmd.get_command(ctx, sub)
            if child is None or getattr(child, "hidden", False):
                continue
            sub_ctx = child.context_class(child, info_name=sub, parent=ctx)
            out += _command(child, sub_ctx, [*path, sub], min(level + 1, 4))
    return out


def cli_reference() -> str:
    """The markdown reference of every `diffpegasus` command."""
    import typer.main

    from diffpegasus._cli import app

    root = typer.main.get_command(app)
    ctx = root.context_class(root, info_name="diffpegasus")
    return "\n".join(_command(root, ctx, ["diffpegasus"], 2))


def on_page_markdown(markdown, page, config, files):
    del page, config, files
    if MARKER in markdown:
        return markdown.replace(MARKER, cli_reference())
    return markdown
