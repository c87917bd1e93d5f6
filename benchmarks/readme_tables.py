"""Copy the benchmark tables into README.md and BENCHMARKS.md, so no figure is retyped.

A document marks where a results file goes::

    <!-- results: engines.md -->
    ...replaced by benchmarks/results/engines.md, its title line dropped...
    <!-- end results -->

Run from the repository root (``make bench`` does it after the benchmarks)::

    .venv/bin/python benchmarks/readme_tables.py          # rewrite the blocks
    .venv/bin/python benchmarks/readme_tables.py --check  # exit 1 if one differs
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
RESULTS = REPO / "benchmarks" / "results"
DOCUMENTS = (REPO / "README.md", REPO / "BENCHMARKS.md")

BLOCK = re.compile(
    r"(?P<open><!-- results: (?P<name>[\w.-]+\.md) -->\n)(?P<body>.*?)"
    r"(?P<close><!-- end results -->)",
    re.DOTALL,
)


def generated(name: str, results: Path = RESULTS) -> str:
    """What a block naming ``name`` holds: the results file without its title line."""
    path = results / name
    if not path.exists():
        raise FileNotFoundError(f"{path} (named by a results block) does not exist")
    lines = path.read_text(encoding="utf-8").strip("\n").split("\n")
    if lines and lines[0].startswith("# "):
        lines = lines[1:]
    return "\n".join(lines).strip("\n") + "\n"


def refresh(text: str, results: Path = RESULTS) -> str:
    """``text`` with every results block replaced by its file's current content."""
    return BLOCK.sub(
        lambda m: m["open"] + generated(m["name"], results) + m["close"],
        text,
    )


def blocks(text: str) -> list[tuple[str, str]]:
    """The (file name, body) of every results block in ``text``."""
    return [(m["name"], m["body"]) for m in BLOCK.finditer(text)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--check", action="store_true", help="only report differences")
    args = parser.parse_args(argv)
    differ = []
    for doc in DOCUMENTS:
        text = doc.read_text(encoding="utf-8")
        new = refresh(text)
        if new != text:
            differ.append(doc.name)
            if not args.check:
                doc.write_text(new, encoding="utf-8")
    if args.check and differ:
        print(f"results blocks out of date in {', '.join(differ)}", file=sys.stderr)
        return 1
    names = ", ".join(differ) if differ else ", ".join(d.name for d in DOCUMENTS)
    print(f"{'rewritten' if differ and not args.check else 'up to date'}: {names}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
