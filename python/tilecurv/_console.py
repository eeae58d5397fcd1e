"""The ``tilecurv`` command installed with the package: the command line's own parser and
commands (the engine's ``main_with_args``), as the standalone binary runs them."""

import sys

from . import _tilecurv


def main() -> None:
    """Runs ``tilecurv`` with this process's arguments and exits with its exit code."""
    sys.stdout.flush()
    sys.exit(_tilecurv.main(["tilecurv", *sys.argv[1:]]))


if __name__ == "__main__":
    main()
