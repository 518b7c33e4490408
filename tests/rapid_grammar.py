"""rapidchecker (the third-party RAPID grammar on PyPI) on the modules the tests write.

Its pyparsing grammar takes ~58 ms per ``CONST robtarget`` declaration and a few ms per other
line: a 300-line module took 9 s, and the suite checked several. A module's robtargets all
come from one formatting function, so the grammar sees the first ``GRAMMAR_ROBTARGETS`` of
them with every other line; the rest must match ``ROBTARGET_LINE``, the exact shape of a
declaration with plain RAPID numbers, which is stricter than the grammar (it refuses ``nan``,
``inf``, a missing bracket or a fifth quaternion element that the grammar might let through).
"""

from __future__ import annotations

import re

from rapidchecker.check import check_format
from rapidchecker.whitespace_checks import check_whitespace

GRAMMAR_ROBTARGETS = 8
_NUM = r"-?\d+(?:\.\d+)?(?:E[+-]?\d+)?"
_NUMS = {n: ",".join([_NUM] * n) for n in (3, 4, 6)}
ROBTARGET_LINE = re.compile(
    rf"^ *(?:LOCAL )?CONST robtarget \w+ := "
    rf"\[\[{_NUMS[3]}\],\[{_NUMS[4]}\],\[{_NUMS[4]}\],\[{_NUMS[6]}\]\];$"
)
_passed: set[str] = set()


def rapidchecker_errors(text: str) -> list[str]:
    """rapidchecker's grammar and whitespace errors of the module ``text``, and any robtarget
    declaration past the first ``GRAMMAR_ROBTARGETS`` that is not of the exact shape."""
    if text in _passed:
        return []
    lines = text.splitlines()
    declarations = [k for k, line in enumerate(lines) if "CONST robtarget " in line]
    shaped = set(declarations[GRAMMAR_ROBTARGETS:])
    errors = [
        f"{k + 1}: not a robtarget declaration of the expected shape: {lines[k]!r}"
        for k in sorted(shaped)
        if not ROBTARGET_LINE.match(lines[k])
    ]
    kept = "\n".join(line for k, line in enumerate(lines) if k not in shaped)
    kept += "\n" if text.endswith("\n") else ""
    errors += [str(e) for e in check_format(kept)] + [str(e) for e in check_whitespace(text)]
    if not errors:
        _passed.add(text)
    return errors
