"""``python -m dolfin_rod run|check SCENE.toml`` and the ``dolfin-rod`` command (see
dolfin_rod.cli).

Ctrl-C before the run has started (imports, model set-up) ends with exit status 130 and
one line instead of a traceback; during the run dolfin_rod.cli stops after the current
step and writes the summary.  SIGTERM (kill, a batch system's time limit, mpirun passing
on Ctrl-C to its ranks) is handled as Ctrl-C.

Python drops a KeyboardInterrupt raised while it runs a weakref callback or a ``__del__``
(it prints "Exception ignored ..." and goes on), so an interrupt that lands there would
be lost and the run would end with exit 0.  The start-up handler therefore also records
the signal (``StartUpInterrupt.received``), and the run loop ends the start-up when it
takes over the signals and finds one recorded (dolfin_rod.run).
"""

import signal
import sys


class StartUpInterrupt:
    """The SIGINT and SIGTERM handler until the run loop starts: raises KeyboardInterrupt
    and remembers that it did (``received``), in case Python drops the exception."""

    def __init__(self):
        self.received = False

    def __call__(self, signum, frame):
        self.received = True
        raise KeyboardInterrupt


def main() -> int:
    handler = StartUpInterrupt()
    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    try:
        from .cli import main as cli_main
        return cli_main()
    except KeyboardInterrupt:
        print("interrupted during start-up", file=sys.stderr, flush=True)
        return 130


if __name__ == "__main__":
    sys.exit(main())
