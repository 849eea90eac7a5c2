"""Running a user's code (a model file, its `read(path)`) inside a command.

Whatever the code does is contained: what it prints goes to stderr (so a command's
`--json` output on stdout stays one valid JSON object), it sees no command-line
arguments and an empty stdin, and `sys.exit`, an argument parser's exit or any
exception becomes one [`LogError`][] naming the file and line.
"""

import contextlib
import io
import pathlib
import sys
import traceback

from ._errors import LogError


def _line_in(e: BaseException, path: str) -> str:
    """` line N` of the innermost frame of the traceback in `path` (for a syntax
    error, the line it names), or ``."""
    if isinstance(e, SyntaxError) and e.lineno and e.filename:
        if pathlib.Path(e.filename).resolve() == pathlib.Path(path).resolve():
            return f" line {e.lineno}"
    frames = [
        f
        for f in traceback.extract_tb(e.__traceback__)
        if pathlib.Path(f.filename).resolve() == pathlib.Path(path).resolve()
    ]
    return f" line {frames[-1].lineno}" if frames else ""


def _where(e: BaseException, path) -> str:
    """`path: line N`, or `path` where no line of it is known."""
    line = _line_in(e, str(path))
    return f"{path}:{line}" if line else str(path)


@contextlib.contextmanager
def contained(path: str, what: str):
    """Run the body as `what` of the user's file `path` (e.g. "at import",
    "in read()"); see the module docstring."""
    captured = io.StringIO()
    failed = True
    argv, stdin = sys.argv, sys.stdin
    sys.argv, sys.stdin = [str(path)], io.StringIO("")
    try:
        with (
            contextlib.redirect_stdout(captured),
            contextlib.redirect_stderr(captured),
        ):
            yield
        failed = False
    except LogError:
        raise
    except SystemExit as e:
        said = [ln for ln in captured.getvalue().splitlines() if ln.strip()]
        last = f" after printing {said[-1].strip()[:120]!r}" if said else ""
        raise LogError(
            f"{_where(e, path)}: the file calls sys.exit({e.code!r}) {what}"
            f"{last} (an argument parser or a script's main?); a model file only "
            "defines things (guard script code with if __name__ == '__main__')"
        ) from None
    except KeyboardInterrupt:
        raise
    except Exception as e:  # the user's code: one line, naming where it failed
        first = str(e).splitlines()[0] if str(e) else ""
        raise LogError(
            f"{_where(e, path)}: {type(e).__name__} {what}: {first}"
        ) from None
    finally:
        sys.argv, sys.stdin = argv, stdin
        # on failure the error line says what matters; on success the user's own
        # warnings are theirs to see
        if not failed and captured.getvalue():
            sys.stderr.write(captured.getvalue())
