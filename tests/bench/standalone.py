"""Running one benchmark part on its own: `python tests/bench/PART.py [--quick]` prints its section."""

from __future__ import annotations

import argparse
import sys


def main(doc: str, run, section) -> None:
    """Parse --quick, run the part (progress to stderr) and print its markdown section."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    print("\n".join(section(run(parser.parse_args().quick, lambda msg: print(msg, file=sys.stderr)))))
