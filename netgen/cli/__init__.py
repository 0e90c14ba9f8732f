"""The `netgen` console command: installs the SIGINT/SIGTERM handlers (netgen.runtime.interrupts) before
the heavy imports of netgen.cli.commands (numpy, scipy, matplotlib: about 0.6 s), so a Ctrl-C or SIGTERM
while they load is one line and exit 130 instead of a traceback; then runs netgen.cli.commands.main, the
error boundary of every subcommand."""

from __future__ import annotations

import sys

from ..runtime.interrupts import EXIT_INTERRUPTED, check, install, internal_error, interrupted, quiet


def main() -> int:
    """Entry point of the `netgen` console script."""
    install()
    try:
        from . import commands as cli

        check()  # a signal an import swallowed
    except KeyboardInterrupt:
        print("netgen: interrupted while starting; nothing was written", file=sys.stderr)
        return EXIT_INTERRUPTED
    except Exception as exc:  # a broken installation: one line, a crash log
        if interrupted(exc):  # numpy/scipy turn a KeyboardInterrupt into these
            print("netgen: interrupted while starting; nothing was written", file=sys.stderr)
            return EXIT_INTERRUPTED
        return internal_error(exc)
    try:
        return cli.main()
    except KeyboardInterrupt:  # between the import and main's own boundary
        print("netgen: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        quiet()


if __name__ == "__main__":
    sys.exit(main())
