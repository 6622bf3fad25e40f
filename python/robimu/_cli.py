"""The ``robimu`` command that the wheel installs: the program itself (the
Rust ``main``), run in this process on the command line's arguments."""

import signal
import sys

from . import _native


def main() -> None:
    """Run ``robimu`` on ``sys.argv`` and exit with its status."""
    # Ctrl-C ends the program as it ends the native one (`record` installs
    # its own handler, which stops a recording cleanly)
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    sys.stdout.flush()
    sys.stderr.flush()
    sys.exit(_native.run_cli(["robimu", *sys.argv[1:]]))


if __name__ == "__main__":
    main()
