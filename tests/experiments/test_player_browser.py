"""The player in a real browser: headless Chromium steps to the worst frame; the screenshot's pixels must show
both skeletons and the worst joint in the error colour.

Marked ``browser`` (``make test-browser``; ``.ci/run`` installs Chromium when it is missing).
"""

from __future__ import annotations

import pytest

from mocapbench.codecs import create
from mocapbench.experiments.browser_check import colour_share, pixels_near, player_facts, player_screenshot
from mocapbench.experiments.player import PlayerEntry, player_html, player_script
from mocapbench.synthetic import sinusoidal_motion

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    """A page beside its player.js (as the report writes it): a positions codec and a rotation codec."""
    folder = tmp_path_factory.mktemp("player")
    motion = sinusoidal_motion(num_frames=150, seed=7)
    entries = []
    for name, params in (("mcb-linf", {"eps_cm": 2.0}), ("quant-rot-zstd", {"rotation_bits": 7})):
        codec = create(name, **params)
        decoded = codec.decode(codec.encode(motion)).positions
        entries.append(PlayerEntry(name, motion.skeleton.names, motion.skeleton.parents, motion.fps,
                                   motion.up_axis, motion.positions(), decoded))
    (folder / "player.js").write_text(player_script())
    path = folder / "player_synthetic.html"
    path.write_text(player_html("player test", entries, script_src="player.js"))
    return path


@pytest.mark.parametrize("entry", [0, 1])
def test_the_worst_frame_shows_both_skeletons_and_the_worst_joint_in_the_error_colour(page, entry, tmp_path):
    fragment = f"entry={entry}&frame=worst"
    facts = player_facts(page, fragment)
    assert facts["entry"] == entry and facts["frame"] == facts["worstFrame"] is not None
    shot = player_screenshot(page, tmp_path / "shot.png", fragment)
    # Both skeletons drawn: the original's grey bones and the decoded blue bones cover part of the canvas.
    assert colour_share(shot, facts["original"]) > 5e-4
    assert colour_share(shot, facts["decoded"]) > 2e-4
    # The worst joint, at its place on the whole-body view, carries the error colour (red, the clip's largest).
    x, y = facts["worstPage"]
    assert pixels_near(shot, (x, y), facts["worstColour"], radius=2) >= 9


def test_the_first_frame_is_not_the_worst_one_and_shows_no_ring(page, tmp_path):
    facts = player_facts(page, "entry=0&frame=0")
    assert facts["frame"] == 0 and facts["worstFrame"] != 0
