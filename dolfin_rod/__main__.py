"""``python -m dolfin_rod run|check SCENE.toml`` and the ``dolfin-rod`` command (see
dolfin_rod.cli).

Ctrl-C before the run has started (imports, model set-up) ends with exit status 130 and
one line instead of a traceback; during the run dolfin_rod.cli stops after the current
step and writes the summary.  SIGTERM (kill, a batch system's time limit, mpirun passing
on Ctrl-C to its ranks) is handled as Ctrl-C.
"""

import signal
import sys


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def main() -> int:
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        from .cli import main as cli_main
        return cli_main()
    except KeyboardInterrupt:
        print("interrupted during start-up", file=sys.stderr, flush=True)
        return 130


if __name__ == "__main__":
    sys.exit(main())
