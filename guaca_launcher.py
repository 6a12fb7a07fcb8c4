"""The `guaca` command's entry point: Ctrl-C ends it with status 130 and one line, from its first instant.

Importing `guaca_py` takes about half a second (numpy, moderngl, every pass and method), and a
console script imports its entry point's package before any of its code runs; so this module
lives outside the package and imports nothing but the standard library until it has taken SIGINT
over. Once the command runs, guaca_py.cli.main handles Ctrl-C itself (a file being written is
removed or left as it was).
"""

import _signal  # what `signal` wraps; `signal` itself imports enum, 10 ms in which Ctrl-C would still be Python's
import os
import sys

#: guaca_py.cli.INTERRUPTED_STATUS (128 + SIGINT), not imported from there: that import is what may be interrupted
INTERRUPTED_STATUS = 130


def _interrupted_while_importing(signum, frame) -> None:
    """Nothing is open or written yet: say so and leave at once, as `guaca` does after Ctrl-C."""
    os.write(2, b"interrupted\n")
    os._exit(INTERRUPTED_STATUS)


def main() -> int:
    """Run `guaca` with the command line's arguments; returns its exit status."""
    # a shell that started guaca in the background with SIGINT ignored keeps it ignored
    ours = _signal.getsignal(_signal.SIGINT) is _signal.default_int_handler
    if ours:
        _signal.signal(_signal.SIGINT, _interrupted_while_importing)
    from guaca_py.cli import main as run

    if ours:
        _signal.signal(_signal.SIGINT, _signal.default_int_handler)  # from here run() catches KeyboardInterrupt
    try:
        status = run()
    except KeyboardInterrupt:  # between the two lines above and run()'s own handler
        print("interrupted", file=sys.stderr)
        status = INTERRUPTED_STATUS
    # The command is done (its files written, or removed): a Ctrl-C from here on would only cut the
    # interpreter's shutdown short, where Python has put SIGINT back to the default and the process
    # dies by the signal, silently, instead of leaving with this status.
    _signal.signal(_signal.SIGINT, _signal.SIG_IGN)
    return status


if __name__ == "__main__":
    sys.exit(main())
