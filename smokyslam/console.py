"""The ``smokyslam`` console entry point.

Loading the command line's modules takes about half a second; a Ctrl-C then would otherwise
print a traceback from inside an import. It gets the one line any later Ctrl-C gets.
"""

from __future__ import annotations

import sys


def main() -> None:
    try:
        from smokyslam.cli import main as cli_main
    except KeyboardInterrupt:
        sys.stderr.write("interrupted\n")
        sys.exit(130)
    cli_main()
