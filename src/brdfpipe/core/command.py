"""The error contract of the ``python -m brdfpipe.…`` command lines.

A module with a command line (:mod:`brdfpipe.acquisition.realism`,
:mod:`brdfpipe.report.sidebyside`) builds its parser with
:class:`OneLineParser` and runs its work through :func:`run`, so that it
behaves as the ``brdfpipe`` command does (:mod:`brdfpipe.cli`, which uses
the same parser and messages):

* an argument error is one line ``PROG: error: ... (see PROG --help)``, exit 2;
* bad input or a failing environment is one line ``PROG: error: ...`` naming
  the file or option (the library's errors are ``ValueError``\\ s whose
  message names it; an ``OSError`` is shown with its path, the output's
  name rather than its temporary sibling's), exit 1;
* an interrupt (Ctrl-C) exits 130; nothing is left half-written, since the
  commands write atomically (:mod:`brdfpipe.core.atomic`);
* anything else is a defect: one line "internal error (...)", exit 1
  (``BRDFPIPE_TRACEBACK=1`` re-raises it to show the traceback).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable
from typing import Any

from brdfpipe.core.atomic import is_out_of_space, output_of

__all__ = ["OneLineParser", "one_line", "os_error_message", "run"]


def one_line(text: object) -> str:
    """``text`` on one line (an error message from a library may hold newlines)."""
    return " ".join(str(text).split())


class OneLineParser(argparse.ArgumentParser):
    """argparse, with an argument error on one line (``PROG: error: ... (see PROG --help)``), exit 2.

    Subcommands made with ``add_subparsers`` are of this class too (their
    ``prog`` is ``PROG CMD``).
    """

    def error(self, message: str) -> Any:  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {one_line(message)} (see {self.prog} --help)\n")


def os_error_message(err: OSError, out: str | None = None) -> str:
    """One line for an OS error: the path involved (an output's, not its temporary sibling's) and what went wrong.

    ``out``: the command's output, named when the error names no path.
    """
    first = None if err.filename is None else str(output_of(os.fsdecode(err.filename)))
    second = None if err.filename2 is None else str(output_of(os.fsdecode(err.filename2)))
    if is_out_of_space(err):
        where = first or out
        return f"no space left on device writing {where}" if where else "no space left on device"
    what = err.strerror or str(err) or type(err).__name__
    if first is not None and second is not None:
        return f"{first} -> {second}: {what}"
    if first is not None:
        return f"{first}: {what}"
    return f"{what} (output {out})" if out else what


def run(prog: str, work: Callable[[], int]) -> int:
    """``work()``'s exit status; on an error, one line ``PROG: error: ...`` on stderr and 1 (130 for Ctrl-C)."""

    def fail(message: str, status: int = 1) -> int:
        print(f"{prog}: error: {one_line(message)}", file=sys.stderr)
        return status

    try:
        return int(work())
    except KeyboardInterrupt:
        return fail("interrupted; nothing was written (outputs are replaced only when complete)", 130)
    except MemoryError:
        return fail("out of memory; nothing was written (an earlier output is kept)")
    except OSError as err:
        return fail(os_error_message(err))
    except ValueError as err:  # the library's errors: the message names the file or option
        return fail(str(err))
    except Exception as err:
        if os.environ.get("BRDFPIPE_TRACEBACK"):
            raise
        return fail(f"internal error ({type(err).__name__}: {one_line(err)}); please report it with the command "
                    "line (BRDFPIPE_TRACEBACK=1 shows the traceback)")
