"""The README's results table, generated from a stored results file (``results/readme.yaml``).

The table sits in README.md between ``<!-- results-table: results/readme.yaml -->`` (the marker names
the results file, relative to the repository) and ``<!-- /results-table -->``;
``scripts/readme_table.py`` (``make readme-table``) rewrites it, tests/test_readme.py checks it.

The results file::

    commands: {score: COMMAND, defects: COMMAND}   # what produced the figures
    defects_n: 100                                 # paired episodes per (base, mutant) pair
    defects_seeds: 881000-881099                   # their seed block
    rows:
      - sut: nilsson
        note: the lane keeper                      # optional, shown after the name
        score: 0.669                               # comparative score D, mean over the seeds
        score_ci: 0.077                            # half-width of its 95 % interval
        n: 10                                      # seeds, paired across the SUTs
        seeds: 882000-882009
        defects: 7 of 12                           # mutants detected, or null: not a base
        makeup: highd
        version: 0.6.0+main (f5de25b)

A missing or malformed field is one :class:`~evoscen_sim.errors.InputError` line naming the file and
the field (``results/readme.yaml: rows[2].score_ci: expected a number (missing)``).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from decimal import ROUND_HALF_UP, Decimal
from pathlib import Path

from evoscen_sim.errors import InputError

HEADER = ("| SUT | score ± 95 % interval | defects detected | make-up | version |\n"
          "|---|---|---|---|---|")
BEGIN = re.compile(r"<!-- results-table: (\S+) -->")
END = "<!-- /results-table -->"
NO_DEFECTS = "–"  # a SUT that was not a base of the sensitivity experiment


@dataclass(frozen=True)
class Row:
    sut: str
    note: str | None
    score: float
    score_ci: float
    n: int
    seeds: tuple[int, int]
    defects: str | None
    makeup: str
    version: str


@dataclass(frozen=True)
class Results:
    name: str  # the file, as named in messages and in the line under the table
    commands: dict[str, str]
    defects_n: int
    defects_seeds: tuple[int, int]
    rows: tuple[Row, ...]


def _field(data: dict, key: str, where: str, name: str, expected: str, ok, optional: bool = False):
    value = data.get(key)
    if value is None and optional:
        return None
    if value is None or not ok(value):
        got = "missing" if key not in data else f"got {value!r}"
        raise InputError(f"{name}: {where}{key}: expected {expected} ({got})")
    return value


def _number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _count(value) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value > 0


def _text(value) -> bool:
    return isinstance(value, str) and value.strip() != "" and "|" not in value and "\n" not in value


def _block(data: dict, key: str, n: int, where: str, name: str) -> tuple[int, int]:
    """A seed block 'A-B' (both ends included) that holds ``n`` seeds."""
    text = _field(data, key, where, name, "a seed block 'A-B'", lambda v: isinstance(v, str)
                  and re.fullmatch(r"\d+-\d+", v.strip()) is not None)
    first, last = (int(x) for x in text.split("-"))
    if last - first + 1 != n:
        raise InputError(f"{name}: {where}{key}: {text} holds {last - first + 1} seeds, expected n = {n}")
    return first, last


def _row(data, i: int, name: str) -> Row:
    where = f"rows[{i}]."
    if not isinstance(data, dict):
        raise InputError(f"{name}: rows[{i}]: expected a mapping (sut, score, score_ci, ...), got {data!r}")
    n = _field(data, "n", where, name, "a positive integer", _count)
    defects = _field(data, "defects", where, name, "'k of m' (k <= m) or null",
                     lambda v: isinstance(v, str) and (m := re.fullmatch(r"(\d+) of (\d+)", v)) is not None
                     and int(m[1]) <= int(m[2]) and int(m[2]) > 0, optional=True)
    return Row(sut=_field(data, "sut", where, name, "a SUT name", _text),
               note=_field(data, "note", where, name, "a text", _text, optional=True),
               score=float(_field(data, "score", where, name, "a number", _number)),
               score_ci=float(_field(data, "score_ci", where, name, "a number >= 0", lambda v: _number(v) and v >= 0)),
               n=n, seeds=_block(data, "seeds", n, where, name), defects=defects,
               makeup=_field(data, "makeup", where, name, "a traffic make-up", _text),
               version=str(_field(data, "version", where, name, "a version", _text)))


def parse_results(data, name: str) -> Results:
    """The results of the parsed YAML ``data`` of the file ``name``; :class:`InputError` if a field is
    missing or malformed."""
    if not isinstance(data, dict):
        raise InputError(f"{name}: expected a mapping with commands, defects_n, defects_seeds and rows")
    commands = _field(data, "commands", "", name, "a mapping with score and defects", lambda v: isinstance(v, dict))
    for key in ("score", "defects"):
        _field(commands, key, "commands.", name, "a command", _text)
    defects_n = _field(data, "defects_n", "", name, "a positive integer", _count)
    defects_seeds = _block(data, "defects_seeds", defects_n, "", name)
    rows = _field(data, "rows", "", name, "a non-empty list", lambda v: isinstance(v, list) and len(v) > 0)
    return Results(name=name, commands=dict(commands), defects_n=defects_n, defects_seeds=defects_seeds,
                   rows=tuple(_row(r, i, name) for i, r in enumerate(rows)))


def load_results(path: Path, name: str | None = None) -> Results:
    """Read and check the results file ``path`` (named ``name`` in messages; default: the path)."""
    import yaml

    name = name or str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"{name}: cannot read: {exc.strerror or exc}") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        at = f" (line {mark.line + 1})" if mark is not None else ""
        raise InputError(f"{name}: not valid YAML{at}: {getattr(exc, 'problem', None) or 'parse error'}") from None
    return parse_results(data, name)


def _three(value: float) -> str:
    """``value`` to 3 decimals, halves rounded up as written in the file (0.7805 -> 0.781, not binary 0.780)."""
    return str(Decimal(repr(value)).quantize(Decimal("0.001"), rounding=ROUND_HALF_UP))


def _seeds(block: tuple[int, int]) -> str:
    return f"{block[0]}–{block[1]}"


def results_markdown(results: Results) -> str:
    """The table (``SUT | score ± 95 % interval | defects detected | make-up | version``) and the line
    under it saying what the score is, its seeds and where the commands are."""
    lines = [HEADER]
    for r in results.rows:
        sut = f"`{r.sut}`" + (f" ({r.note})" if r.note else "")
        lines.append(f"| {sut} | {_three(r.score)} ± {_three(r.score_ci)} | {r.defects or NO_DEFECTS} | `{r.makeup}` "
                     f"| {r.version} |")
    designs = {(r.n, r.seeds) for r in results.rows}
    if len(designs) == 1:
        (n, block), = designs
        over = f"n = {n} seeds ({_seeds(block)})"
    else:
        over = f"the seeds of each row ({results.name})"
    lines += ["", f"Score: D (comparative score, D = P·(0.6·S + 0.2·L + 0.2·X), [docs/evaluation.md](docs/evaluation.md) "
              f"§10), mean ± half-width of the 95 % interval over {over}, every SUT on the same seeds (paired by "
              f"seed); defects detected: library defects (`frozen`, a profile, not counted) whose paired interval "
              f"of ΔD = intact − mutant lies above zero, "
              f"n = {results.defects_n} paired episodes ({_seeds(results.defects_seeds)}) of the sensitivity "
              f"experiment's scenario (the challenge scenario by default, docs/challenges.md); the commands: "
              f"[{results.name}]({results.name})."]
    return "\n".join(lines)


def results_file(readme: str) -> str:
    """The results file the README's marker names; :class:`InputError` if the markers are missing."""
    m = BEGIN.search(readme)
    if m is None or END not in readme[m.end():]:
        raise InputError(f"README.md: markers <!-- results-table: FILE --> ... {END} not found")
    return m[1]


def readme_table(readme: str) -> str:
    """The text between the README's results-table markers (stripped)."""
    name = results_file(readme)
    return readme.split(f"<!-- results-table: {name} -->", 1)[1].split(END, 1)[0].strip()


def rewrite_readme(readme: str, repo: Path) -> str:
    """``readme`` with the table between its markers generated from the results file they name."""
    name = results_file(readme)
    table = results_markdown(load_results(Path(repo) / name, name))
    begin = f"<!-- results-table: {name} -->"
    head, rest = readme.split(begin, 1)
    return f"{head}{begin}\n{table}\n{END}{rest.split(END, 1)[1]}"


def write_readme_table(readme: Path, repo: Path, *, check: bool = False) -> int:
    """``scripts/readme_table.py``: rewrite ``readme``'s results table from the results file its marker
    names (relative to ``repo``); with ``check`` write nothing and return 1 (one line on stderr) if it
    differs. A malformed results file or an unreadable README is an :class:`InputError`."""
    import sys

    try:
        text = readme.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"{readme}: cannot read: {exc.strerror or exc}") from None
    new = rewrite_readme(text, repo)
    if check:
        if new != text:
            print(f"README.md: the results table differs from {results_file(text)}: run make readme-table",
                  file=sys.stderr)
            return 1
        return 0
    if new != text:
        readme.write_text(new, encoding="utf-8")
    print(f"README.md: results table {'updated' if new != text else 'unchanged'}")
    return 0
