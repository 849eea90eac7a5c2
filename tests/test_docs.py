"""The documentation builds and what it shows runs.

- `mkdocs build --strict` succeeds (broken links, unresolved API references and
  missing pages are errors); the command-line and API reference pages are generated
  from the program during the build.
- Every ```python and ```bash block of every page runs, in page order, in a fresh
  folder per page (python blocks in one namespace per page, bash blocks in a shell
  whose `python` and `diffpegasus` are this environment's). A block titled with a
  file name (```python title="my_aircraft.py"```, ```toml title="columns.toml"```)
  is that file: it is written to the folder for the blocks after it. A block that
  must not run here (it takes minutes, or needs data the repository does not ship)
  says so in its visible title: ```bash title="Not run here: REASON"```.
- No page names an issue, a work session, a commit or a path outside the
  repository.
"""

import os
import pathlib
import re
import subprocess
import sys

import pytest


ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
FENCE = re.compile(r'^```(python|bash|toml|json|text)(?:\s+title="([^"]*)")?\s*$')
FILE = re.compile(r"^[\w.-]+\.(py|toml|json|csv|txt)$")
NOT_RUN = re.compile(r"^Not run here: .{8,}")


def _pages():
    return sorted(p for p in DOCS.rglob("*.md") if "_hooks" not in p.parts)


def _blocks(page: pathlib.Path):
    """(language, title, code, line) of the page's python and bash blocks."""
    lines = page.read_text(encoding="utf-8").splitlines()
    out, i = [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if m is None:
            i += 1
            continue
        start, body = i + 1, []
        i += 1
        while i < len(lines) and lines[i].rstrip() != "```":
            body.append(lines[i])
            i += 1
        out.append((m.group(1), m.group(2) or "", "\n".join(body) + "\n", start))
        i += 1
    return out


def _runs(language, title):
    return not NOT_RUN.match(title) and (
        FILE.match(title) or language in ("python", "bash")
    )


RUNNABLE = [p for p in _pages() if any(_runs(la, t) for la, t, _, _ in _blocks(p))]


def test_blocks_are_found_and_marked():
    """Every python/bash fence is one the runner sees (top level, no other header
    form) and a skipped one gives its reason."""
    for page in _pages():
        text = page.read_text(encoding="utf-8")
        for n, line in enumerate(text.splitlines(), start=1):
            stripped = line.strip()
            if re.match(r"^```(python|bash|py|sh|shell|console|toml|json)\b", stripped):
                assert FENCE.match(line), (
                    f"{page.relative_to(ROOT)}:{n}: a code block the docs tests "
                    f"cannot read: {line!r} (top level, ```python or ```bash, "
                    'optionally title="...")'
                )
        for _, title, _, line in _blocks(page):
            if title.lower().startswith("not run"):
                assert NOT_RUN.match(title), f"{page}:{line}: say why it is not run"


@pytest.mark.parametrize(
    "page", RUNNABLE, ids=[str(p.relative_to(DOCS)) for p in RUNNABLE]
)
def test_code_blocks_run(page, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    env = dict(os.environ)
    env["PATH"] = os.path.dirname(sys.executable) + os.pathsep + env.get("PATH", "")
    src = str(ROOT / "src")
    env["PYTHONPATH"] = src + os.pathsep + env.get("PYTHONPATH", "")
    env["DIFFPEGASUS_DOCS_ROOT"] = str(ROOT)  # pages may copy the repository's examples
    namespace: dict = {"__name__": "__docs__"}
    for language, title, code, line in _blocks(page):
        if not _runs(language, title):
            continue
        where = f"{page.relative_to(ROOT)}:{line}"
        if FILE.match(title):
            if language == "python":
                compile(code, where, "exec")  # a file shown is valid Python
            (tmp_path / title).write_text(code, encoding="utf-8")
        elif language == "python":
            exec(compile(code, where, "exec"), namespace)  # noqa: S102
        else:
            done = subprocess.run(
                ["bash", "-euo", "pipefail", "-c", code],
                cwd=tmp_path,
                env=env,
                capture_output=True,
                text=True,
                timeout=300,
            )
            assert done.returncode == 0, (
                f"{where} exited {done.returncode}\n{done.stdout}\n{done.stderr}"
            )


FORBIDDEN = [
    (re.compile(r"\b[Ii]ssues? #?\d+|\(#\d+\)|\B#\d{1,3}\b"), "an issue number"),
    (re.compile(r"\bsession\b", re.I), "a work session"),
    (
        re.compile(r"/work/|\.\./shared|\bshared/data\b|\bnotes/"),
        "a path outside the repository",
    ),
    (re.compile(r"\bSPEC\b"), "the internal specification"),
    (
        re.compile(
            r"\b(?<![.\d])(?=[0-9a-f]*[a-f])(?=[0-9a-f]*\d)[0-9a-f]{7,40}\b(?![-+]\d)"
        ),
        "a commit hash",
    ),
    (re.compile(r"\bload \d+(\.\d+)?-\d"), "an edit note about machine load"),
]


@pytest.mark.parametrize("path", [ROOT / "README.md", *_pages()], ids=lambda p: p.name)
def test_no_internal_references(path):
    text = path.read_text(encoding="utf-8")
    for pattern, what in FORBIDDEN:
        m = pattern.search(text)
        assert m is None, (
            f"{path.relative_to(ROOT)} mentions {what}: "
            f"{text[max(0, m.start() - 60) : m.end() + 60]!r}"
        )


def test_the_site_builds_strict(tmp_path):
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT / "src") + os.pathsep + env.get("PYTHONPATH", "")
    env["NO_MKDOCS_2_WARNING"] = "1"
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "mkdocs",
            "build",
            "--strict",
            "-q",
            "-d",
            str(tmp_path / "site"),
        ],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-4000:]
    cli = (tmp_path / "site" / "reference" / "cli" / "index.html").read_text()
    api = (tmp_path / "site" / "reference" / "api" / "index.html").read_text()
    # the generated pages hold what the program has (a command, an option, a name)
    assert "diffpegasus fit" in cli and "--columns" in cli
    assert "dp.fit" in api and "dp.Model" in api


def _commands():
    """Every `diffpegasus ...` line of every bash block, run or not (continuation
    lines joined, comments and redirections dropped)."""
    import shlex

    out = []
    for page in [*_pages(), ROOT / "README.md"]:
        for language, _, code, line in _blocks(page):
            if language != "bash":
                continue
            for text in code.replace("\\\n", " ").splitlines():
                text = text.strip()
                for prefix in ("srun ", "if "):
                    text = text.removeprefix(prefix)
                if not text.startswith("diffpegasus "):
                    continue
                words = shlex.split(text, comments=True)
                words = words[
                    : next(
                        (
                            i
                            for i, w in enumerate(words)
                            if w in (">", "2>", ";", "&&", "|", "2>&1")
                        ),
                        len(words),
                    )
                ]
                out.append((f"{page.relative_to(ROOT)}:{line}", words))
    return out


def test_every_command_shown_exists():
    """The commands the pages show, run or not, name commands and options the
    program has (the pages that cannot run still follow the command line)."""
    import typer.main

    from diffpegasus._cli import app

    root = typer.main.get_command(app)
    for where, words in _commands():
        cmd, ctx = root, root.context_class(root, info_name="diffpegasus")
        rest = words[1:]
        while rest and hasattr(cmd, "get_command") and not rest[0].startswith("-"):
            sub = cmd.get_command(ctx, rest[0])
            assert sub is not None, f"{where}: no command {' '.join(words[:2])!r}"
            cmd, ctx = sub, sub.context_class(sub, info_name=rest[0], parent=ctx)
            rest = rest[1:]
        known = {"--help", "--no-cache"}
        for p in cmd.get_params(ctx):
            known.update(getattr(p, "opts", ()), getattr(p, "secondary_opts", ()))
        for w in rest:
            if w.startswith("--"):
                assert w.split("=")[0] in known, (
                    f"{where}: {' '.join(words)}: no option {w}"
                )
