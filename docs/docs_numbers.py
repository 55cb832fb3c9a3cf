"""Measured numbers in the guides: the regions a script regenerates, and their comparison.

A guide quotes a script's output between two markers::

    <!-- numbers: NAME -->
    ...the lines the script printed under NAME...
    <!-- /numbers -->

A script that backs a guide (``docs/<guide>_numbers.py`` or one in ``bench/``) prints each of
its regions in that form, markers included, and records the last output in
``docs/numbers/<script>.txt``. ``tests/test_docs_numbers.py`` checks that every region of the
guides matches the recorded output, and, where the script is fast, that the recorded output
matches a fresh run.

Two blocks agree when their words agree and every number agrees within the tolerance:

* integers (counts: passes, simulations, samples) exactly;
* other numbers to one unit of the last digit the page prints, or within the relative
  tolerance ``rel`` where the marker states one (``<!-- numbers: NAME rel=0.01 -->``);
* numbers in a table column whose heading, or a table row whose first cell, names a time
  (``wall``, ``time``, ``µs``, ``ms``, ``speed``, ``(s)``), or a ratio column (``÷ …``)
  right of such a column, are not compared at all: timings depend on the machine and are
  never asserted (the page shows the command that prints them).

Numbers are read as written on the page: ``−`` is a minus sign, ``1.2·10⁻⁸`` and ``1.2×10⁻⁸``
are 1.2e-8.

    python docs/docs_numbers.py write SCRIPT_OUTPUT.txt    # put the regions into their guides
    python docs/docs_numbers.py check SCRIPT_OUTPUT.txt    # compare (exit 1 naming each difference)
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
RECORDED = DOCS / "numbers"

_BEGIN = re.compile(r"<!--\s*numbers:\s*(?P<name>[\w.-]+)(?P<options>[^>]*?)\s*-->")
_END = "<!-- /numbers -->"
_SUPERSCRIPT = str.maketrans("⁰¹²³⁴⁵⁶⁷⁸⁹⁻⁺", "0123456789-+")
# a number as printed: 1, −0.25, 3.5e-07, 1.2·10⁻⁸, 4.0×10⁵ (not a digit inside a word: Cm0)
NUMBER = re.compile(
    r"(?<![\w.])[−+-]?\d+(?:\.\d+)?(?:[eE][−+-]?\d+|[·×]10[⁻⁺]?[⁰¹²³⁴⁵⁶⁷⁸⁹]+)?(?![\w.])"
)
TIME_HEADING = re.compile(r"(?i)\bwall\b|\btime\b|µs|\bms\b|speed|per sample|\(s\)")


def _options(text: str) -> dict[str, str]:
    return dict(re.findall(r"(\w+)=(\S+)", text))


def regions(text: str) -> dict[str, tuple[str, dict[str, str]]]:
    """{name: (the lines between the markers, the marker's options)} of a page or an output."""
    found: dict[str, tuple[str, dict[str, str]]] = {}
    for match in _BEGIN.finditer(text):
        end = text.find(_END, match.end())
        if end < 0:
            raise ValueError(f"region {match.group('name')!r} has no closing {_END}")
        name = match.group("name")
        if name in found:
            raise ValueError(f"region {name!r} appears twice")
        found[name] = (text[match.end() : end].strip("\n"), _options(match.group("options")))
    return found


def value(token: str) -> float:
    """The number a printed token stands for (``−1.2·10⁻⁸`` → -1.2e-08)."""
    token = token.replace("−", "-")
    parts = re.split(r"[·×]10", token, maxsplit=1)
    if len(parts) == 2:
        return float(parts[0]) * 10.0 ** int(parts[1].translate(_SUPERSCRIPT))
    return float(token)


def _last_digit(token: str) -> float:
    """The unit of the last printed digit of ``token`` (0.0123 → 1e-4, 1.2e-07 → 1e-8)."""
    token = token.replace("−", "-")
    parts = re.split(r"[·×]10|[eE]", token, maxsplit=1)
    mantissa = parts[0]
    exponent = int(parts[1].translate(_SUPERSCRIPT)) if len(parts) > 1 else 0
    decimals = len(mantissa.split(".")[1]) if "." in mantissa else 0
    return 10.0 ** (exponent - decimals)


def _is_integer(token: str) -> bool:
    return re.fullmatch(r"[−+-]?\d+", token) is not None


def same_number(quoted: str, fresh: str, rel: float | None) -> bool:
    """Whether two printed numbers agree (see the module docstring)."""
    if _is_integer(quoted) and _is_integer(fresh):
        return value(quoted) == value(fresh) or (
            rel is not None and math.isclose(value(quoted), value(fresh), rel_tol=rel)
        )
    a, b = value(quoted), value(fresh)
    # |a − b| ≤ one unit of the last digit the page prints (and rounding on either side)
    if abs(a - b) <= _last_digit(quoted) * (1 + 1e-9) or math.isclose(a, b, rel_tol=1e-12):
        return True
    return rel is not None and math.isclose(a, b, rel_tol=rel)


def _skeleton(line: str) -> str:
    return NUMBER.sub("#", line.replace("−", "-"))


def _timed_columns(header: str) -> set[int]:
    """The columns of a table heading that hold times: a heading naming a time, and a ratio
    (``÷ …``, ``× …``) right of such a column."""
    timed: set[int] = set()
    for i, cell in enumerate(header.split("|")):
        ratio = cell.strip().startswith(("÷", "×"))
        if TIME_HEADING.search(cell) or (ratio and i - 1 in timed):
            timed.add(i)
    return timed


def _untimed(line: str, timed: set[int]) -> str:
    if not line.startswith("|"):
        return line
    cells = line.split("|")
    if len(cells) > 2 and TIME_HEADING.search(cells[1]):
        return cells[1]  # a row of wall times: its label only
    return "|".join("" if i in timed else cell for i, cell in enumerate(line.split("|")))


def differences(quoted: str, fresh: str, rel: float | None = None) -> list[str]:
    """Each line of ``quoted`` that disagrees with ``fresh`` (empty: they agree)."""
    old = [line for line in quoted.splitlines() if line.strip()]
    new = [line for line in fresh.splitlines() if line.strip()]
    if len(old) != len(new):
        return [f"{len(old)} lines quoted, {len(new)} printed"]
    found: list[str] = []
    timed: set[int] = set()
    for index, (line_old, line_new) in enumerate(zip(old, new, strict=True)):
        following = old[index + 1] if index + 1 < len(old) else ""
        if line_old.startswith("|") and following.startswith("|-"):
            timed = _timed_columns(line_old)  # a table's heading row
        elif not line_old.startswith("|"):
            timed = set()
        a, b = _untimed(line_old, timed), _untimed(line_new, timed)
        numbers_a, numbers_b = NUMBER.findall(a), NUMBER.findall(b)
        if _skeleton(a) != _skeleton(b) or len(numbers_a) != len(numbers_b):
            found.append(f"quoted: {line_old}\n printed: {line_new}")
            continue
        if not all(same_number(x, y, rel) for x, y in zip(numbers_a, numbers_b, strict=True)):
            found.append(f"quoted: {line_old}\n printed: {line_new}")
    return found


def compare(page_text: str, output_text: str) -> list[str]:
    """Each region of ``output_text`` that the page lacks or quotes differently."""
    page, output = regions(page_text), regions(output_text)
    problems = []
    for name, (fresh, _) in output.items():
        if name not in page:
            problems.append(f"{name}: not quoted on the page")
            continue
        quoted, options = page[name]
        rel = float(options["rel"]) if "rel" in options else None
        problems += [f"{name}: {line}" for line in differences(quoted, fresh, rel)]
    return problems


def guide_of(output_text: str) -> Path:
    """The guide an output belongs to: its first line ``<!-- guide: docs/NAME.md -->``."""
    match = re.search(r"<!--\s*guide:\s*(\S+)\s*-->", output_text)
    if not match:
        raise ValueError("the output names no guide (<!-- guide: docs/NAME.md -->)")
    return DOCS.parent / match.group(1)


def write(page_text: str, output_text: str) -> str:
    """The page with each region replaced by the output's (options of the page kept)."""
    output = regions(output_text)

    pieces, position = [], 0
    for match in _BEGIN.finditer(page_text):
        end = page_text.find(_END, match.end())
        pieces.append(page_text[position : match.start()])
        name = match.group("name")
        body = output[name][0] if name in output else page_text[match.end() : end].strip("\n")
        pieces.append(f"{match.group(0)}\n{body}\n")
        position = end
    pieces.append(page_text[position:])
    return "".join(pieces)


def record(name: str, output_text: str) -> Path:
    """Keep a script's output as ``docs/numbers/NAME.txt`` (the record the tests read)."""
    RECORDED.mkdir(exist_ok=True)
    path = RECORDED / f"{name}.txt"
    path.write_text(output_text, encoding="utf-8")
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("action", choices=("write", "check"))
    parser.add_argument("output", type=Path, help="a script's output (docs/numbers/NAME.txt)")
    arguments = parser.parse_args(argv)
    output_text = arguments.output.read_text(encoding="utf-8")
    page = guide_of(output_text)
    page_text = page.read_text(encoding="utf-8")
    if arguments.action == "write":
        page.write_text(write(page_text, output_text), encoding="utf-8")
        return 0
    problems = compare(page_text, output_text)
    print("\n".join(problems) or f"{page.name} agrees with {arguments.output.name}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
