"""How a benchmark script ends: ``raise SystemExit(run_script(main))``, so a missing data folder is one line."""

from __future__ import annotations

__all__ = ["run_script"]


def run_script(main) -> int:
    """Run a benchmark script's ``main()``: a missing data folder is one line on stderr and exit 2, not a traceback.

    Every script that reads the CMU (or another downloaded) data ends with ``raise SystemExit(run_script(main))``.
    """
    import sys

    from mocapbench.datasets.cmu import DataNotFoundError

    try:
        return int(main() or 0)
    except DataNotFoundError as error:
        spec = getattr(sys.modules["__main__"], "__spec__", None)
        print(f"{spec.name if spec else sys.argv[0]}: {' '.join(str(error).split())}", file=sys.stderr)
        return 2
