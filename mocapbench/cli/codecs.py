"""``mocapbench codecs``: the registered codecs, their parameters, and those unavailable here with the reason."""

from __future__ import annotations

__all__ = ["add_parser", "run"]


def run(args) -> None:
    """Print every codec's first docstring line and its config fields."""
    from mocapbench.codecs import CODECS, UNAVAILABLE

    for name in sorted(CODECS):
        cls = CODECS[name]
        print(f"{name}: {(cls.__doc__ or '').strip().splitlines()[0]}")
        print(f"    [{_traits(name)}]")
        for line in cls.Config.describe_fields().splitlines():
            print(f"    {line}")
    for name in sorted(set(UNAVAILABLE) - set(CODECS)):
        print(f"{name}: unavailable here: {UNAVAILABLE[name]}")


def _traits(name: str) -> str:
    """What a user choosing a codec asks first: rotations or positions, a model or not (from the class, whose
    defaults decide; nothing is instantiated, so the listing stays cheap)."""
    from mocapbench.codecs import CODECS, Codec

    cls = CODECS[name]
    output = "outputs rotations (BVH/glTF)" if cls.codes_rotations else "outputs joint positions only (.npy)"
    needs = cls.needs_model if isinstance(cls.needs_model, bool) else True  # a property: its defaults need one
    if needs:
        model = f"needs a model fit for the skeleton (`mocapbench fit --codec {name}`; one ships for 31-joint CMU)"
    elif cls.fit is not Codec.fit:
        model = "can use a model fit for the skeleton (`mocapbench fit`), runs without one"
    else:
        model = "needs no model"
    return f"{output}; {model}; family {cls.family}"


def add_parser(commands) -> None:
    """Register ``codecs`` on the CLI's sub-parsers."""
    listing = commands.add_parser("codecs", help="list the registered codecs and their parameters")
    listing.set_defaults(run=run)
