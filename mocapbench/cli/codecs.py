"""``mocapbench codecs``: the registered codecs, their parameters, and those unavailable here with the reason."""

from __future__ import annotations

__all__ = ["add_parser", "run"]


def run(args) -> None:
    """Print every codec's first docstring line and its config fields."""
    from mocapbench.codecs import CODECS, UNAVAILABLE

    for name in sorted(CODECS):
        cls = CODECS[name]
        print(f"{name}: {(cls.__doc__ or '').strip().splitlines()[0]}")
        for line in cls.Config.describe_fields().splitlines():
            print(f"    {line}")
    for name in sorted(set(UNAVAILABLE) - set(CODECS)):
        print(f"{name}: unavailable here: {UNAVAILABLE[name]}")


def add_parser(commands) -> None:
    """Register ``codecs`` on the CLI's sub-parsers."""
    listing = commands.add_parser("codecs", help="list the registered codecs and their parameters")
    listing.set_defaults(run=run)
