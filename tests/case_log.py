"""The message each bad-input case ends in, for a closing note's table: with ``BRDFPIPE_CASE_LOG=FILE``
set, the error-contract tests append one ``case<TAB>message`` line per case (temporary paths shortened)."""

from __future__ import annotations

import os
import re

_TMP = re.compile(r"/tmp/pytest-of-[^/]+/pytest-\d+/[^/\s:]+")


def record(case: str, message: str) -> None:
    path = os.environ.get("BRDFPIPE_CASE_LOG")
    if path:
        with open(path, "a", encoding="utf-8") as fh:
            fh.write(f"{case}\t{_TMP.sub('<tmp>', message)}\n")
