"""mcb-rot encoder: attempts side by side are the attempts one by one, and the rate search's prefetch changes no
stream."""

from __future__ import annotations

import numpy as np
import pytest

from mocapbench import metrics
from mocapbench.codecs import create
from mocapbench.codecs.mcb_rot import codec as rot_codec
from mocapbench.codecs.mcb_rot.refine import most_helpful
from mocapbench.codecs.mcb_rot.quaternions import exp_map
from mocapbench.motion import Motion
from mocapbench.synthetic import rig_motion, sinusoidal_motion


def _encoder_of(motion: Motion, monkeypatch, **config):
    """The ``_Encoder`` the codec builds for ``motion`` (caught at the rate search) and the stream it wrote."""
    caught = {}
    search = rot_codec._search

    def catching(attempt, *args, **kwargs):
        caught["encoder"] = attempt.__self__
        return search(attempt, *args, **kwargs)

    monkeypatch.setattr(rot_codec, "_search", catching)
    data = create("mcb-rot", **config).encode(motion)
    monkeypatch.setattr(rot_codec, "_search", search)
    return caught["encoder"], data


def _spinning(num_frames: int) -> Motion:
    """A root spinning through several turns and a joint swinging through +-180 deg: re-referenced segments."""
    base = sinusoidal_motion(num_frames=num_frames, seed=4)
    t = np.arange(num_frames) / 120.0
    quats = np.array(base.rotations)
    quats[:, 0] = exp_map(np.stack([0 * t, 3 * np.pi * t, 0 * t], axis=1))
    quats[:, 18] = exp_map(np.stack([np.pi * np.sin(2 * t) + 0.01, 0 * t, 0 * t], axis=1))
    return Motion(base.skeleton, base.fps, base.root_positions, quats)


MOTIONS = {
    "sinusoidal": lambda: sinusoidal_motion(num_frames=90, seed=2),
    "spinning": lambda: _spinning(150),
    "quadruped with a shell": lambda: rig_motion(num_joints=30, topology="quadruped", num_frames=70, seed=3),
}


@pytest.mark.parametrize("name", sorted(MOTIONS))
def test_attempts_side_by_side_are_the_attempts_one_by_one(name, monkeypatch):
    config = {"eps_cm": 0.1, "shell_cm": 3.0 if "shell" in name else 0.0}
    encoder, _ = _encoder_of(MOTIONS[name](), monkeypatch, **config)
    if name == "spinning":
        assert encoder.info.overrides, "the motion should re-reference segments"
    requests = [(rot_codec._SEARCH_GRID[7], None), (rot_codec._SEARCH_GRID[5], None), (rot_codec._SEARCH_GRID[9], 0.0),
                (rot_codec._SEARCH_GRID[8], 0.0)]
    batched = encoder.attempts_of(requests)
    for (multiplier, slope), together in zip(requests, batched):
        alone = encoder.attempt(multiplier, slope)
        # The start (first) finishes; the others are given up only where they exceed its size.
        if together.size == np.inf:
            assert alone.size > batched[0].size
            continue
        assert together.size == alone.size and together.base == alone.base
        np.testing.assert_array_equal(together.info.dc, alone.info.dc)
        for segment, coefficients in alone.coefficients.items():
            np.testing.assert_array_equal(together.coefficients[segment], coefficients)
        for mine, theirs in zip(together.corrections, alone.corrections):
            np.testing.assert_array_equal(mine, theirs)
    assert batched[0].size < np.inf


def test_side_by_side_attempts_over_a_budget_are_given_up(monkeypatch):
    encoder, _ = _encoder_of(MOTIONS["sinusoidal"](), monkeypatch, eps_cm=0.1)
    requests = [(rot_codec._SEARCH_GRID[k], None) for k in (6, 7, 8)]
    sizes = [attempt.size for attempt in encoder.attempts_of(requests)]
    budget = sorted(sizes)[1]  # the middle size: the largest attempt is over it
    capped = [attempt.size for attempt in encoder.attempts_of(requests, budget=budget)]
    for size, size_capped in zip(sizes, capped):
        assert size_capped == (size if size <= budget else np.inf)


@pytest.mark.parametrize("name", sorted(MOTIONS))
def test_the_prefetch_changes_no_stream(name, monkeypatch):
    """Short clips prefetch attempts side by side; the walk ends where it would without them."""
    motion = MOTIONS[name]()
    config = {"eps_cm": 0.05, "shell_cm": 3.0 if "shell" in name else 0.0}
    assert motion.num_frames <= rot_codec._PREFETCH_FRAMES
    encoder, prefetched = _encoder_of(motion, monkeypatch, **config)
    assert encoder.attempts > 4
    monkeypatch.setattr(rot_codec, "_PREFETCH_FRAMES", 0)
    plain = create("mcb-rot", **config).encode(motion)
    assert prefetched == plain
    decoded = create("mcb-rot").decode(prefetched)
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= config["eps_cm"]


@pytest.mark.parametrize("name", sorted(MOTIONS))
def test_base_estimates_side_by_side_are_the_estimates_one_by_one(name, monkeypatch):
    import dataclasses

    from mocapbench.codecs.mcb_rot.rate import base_bytes, base_bytes_many

    encoder, _ = _encoder_of(MOTIONS[name](), monkeypatch, eps_cm=0.1)
    infos = [encoder.info.replace(settings=dataclasses.replace(encoder.info.settings, multiplier=m, slope=s))
             for m, s in ((4.0, 1.0), (11.3125, 0.0), (32.0, 1.0))]
    quantized = encoder.compensator.quantize_many(infos)
    infos = [info.replace(dc=dc) for info, (dc, _) in zip(infos, quantized)]
    together = base_bytes_many(infos, encoder.compensator.last_quantized)
    alone = [base_bytes(info, coefficients) for info, (_, coefficients) in zip(infos, quantized)]
    assert together == alone
    assert alone[0] > alone[1] > alone[2] > 0  # finer steps cost more: the attempts differ


@pytest.mark.parametrize("seed", range(4))
def test_most_helpful_picks_the_candidate_a_direct_count_picks(seed):
    """most_helpful (scored on the (missing joint, candidate ancestor) pairs only) keeps, per row, the candidate
    whose first-order correction most reduces a missing joint's error, as a loop over rows and candidates finds."""
    from types import SimpleNamespace

    from mocapbench.codecs.mcb_rot import quaternions as quat

    rng = np.random.default_rng(seed)
    num_frames, num_joints = 40, 12
    parents = np.array([-1, 0, 1, 2, 0, 4, 5, 0, 7, 8, 9, 9])
    movers = np.zeros((num_joints, num_joints), dtype=bool)
    for joint in range(1, num_joints):
        movers[joint] = movers[parents[joint]]
        movers[joint, parents[joint]] = True
    placed = rng.normal(0, 30, (num_frames, num_joints, 3))
    error = rng.normal(0, 0.2, (num_frames, num_joints, 3))
    glob = quat.exp_map(rng.normal(0, 1, (num_frames, num_joints, 3)))
    relative = quat.exp_map(rng.normal(0, 0.01, (num_frames, num_joints, 3)))
    root_error = rng.normal(0, 0.05, (num_frames, 3))
    missing = rng.random((num_frames, num_joints)) < 0.2
    missing[:, 0] = False
    fix = (rng.random((num_frames, num_joints + 1)) < 0.4) & missing.any(axis=1)[:, None]
    fix[5] = False  # a row with nothing to fix stays empty
    out = most_helpful(fix, missing, placed, error, glob, relative, root_error,
                                  SimpleNamespace(movers=movers))
    for row in range(num_frames):
        candidates = np.flatnonzero(fix[row])
        if not candidates.size:
            assert not out[row].any()
            continue
        gains = []
        for slot in candidates:
            best = -1e300
            for joint in np.flatnonzero(missing[row]):
                if slot == 0:
                    moved = root_error[row]
                elif movers[joint, slot - 1]:
                    rel = relative[row, slot - 1] * (1.0 if relative[row, slot - 1, 3] >= 0 else -1.0)
                    omega = quat.rotate(glob[row, slot - 1], quat.log_map(rel))
                    moved = np.cross(omega, placed[row, joint] - placed[row, slot - 1])
                else:
                    continue
                size = np.linalg.norm(error[row, joint])
                best = max(best, size - np.linalg.norm(error[row, joint] - moved))
            gains.append(best)
        assert out[row].sum() == 1
        picked = int(np.flatnonzero(out[row])[0])
        assert gains[list(candidates).index(picked)] == pytest.approx(max(gains), abs=1e-12)


def test_segment_lengths_searched_are_the_grid_its_half_and_even_splits_of_a_short_clip():
    """The lengths tried below 60 fps: the config's first, its half, then (a clip of up to 4 x segment_frames) the
    even splits ceil(F / k) from the fewest segments of at most segment_frames, never longer (the latency) nor
    shorter than a quarter of it; a long clip tries the two grids only."""
    from mocapbench.codecs.mcb_rot.codec import _segment_lengths

    assert _segment_lengths(130, 128) == [128, 64, 65, 44, 33]
    assert _segment_lengths(220, 128) == [128, 64, 110, 74, 55, 44]
    assert _segment_lengths(513, 128) == [128, 64]
    for frames in range(1, 600):
        lengths = _segment_lengths(frames, 128)
        assert lengths[:2] == [128, 64] and len(set(lengths)) == len(lengths)
        assert all(32 <= length <= 128 for length in lengths)
        for length in lengths[2:]:  # an even split: every segment but the last full, the last at most one shorter
            count = -(-frames // length)
            assert length * (count - 1) < frames and frames - length * (count - 1) >= length - count + 1


def test_below_60_fps_the_smallest_of_the_segment_lengths_is_kept(monkeypatch):
    """At 30 fps the encoder tries each length of the search (128 and 64 frames, even splits of a short clip): with
    the screen (the default) its stream is no larger than the config's length alone (that length's whole rate search
    is its first candidate); with every length searched no larger than that, nor than the screened stream (its
    candidates are a superset of the screen's: the same screens, the same searches from the same seeds, and more).
    A length coded alone starts its rate search elsewhere than the search seeded by a screen, so on a size curve
    with two minima it may end smaller than either: that is not asserted. Either way the length is the one the
    stream says, and it decodes within eps. At 120 fps it writes the stream it writes without the search."""
    from mocapbench.codecs import container
    from mocapbench.codecs.mcb_rot.codec import _segment_lengths
    from mocapbench.codecs.mcb_rot.stream import read_info

    slow = sinusoidal_motion(num_frames=300, seed=9).every(4)  # 30 fps
    sizes = {}
    for frames in _segment_lengths(slow.num_frames, 128):
        codec = create("mcb-rot", eps_cm=0.2, segment_frames=frames, segment_search=False)
        sizes[frames] = len(codec.encode(slow))
    assert len(set(sizes.values())) > 1  # the lengths code this clip differently: the choice matters
    screened = create("mcb-rot", eps_cm=0.2).encode(slow)
    assert len(screened) <= sizes[128]
    monkeypatch.setattr(rot_codec, "_SCREENED_SEARCHES", len(sizes))
    monkeypatch.setattr(rot_codec, "_SCREEN_MARGIN", np.inf)
    searched = create("mcb-rot", eps_cm=0.2)
    data = searched.encode(slow)
    assert len(data) <= sizes[128] and len(data) <= len(screened)
    header, payload = container.unpack(data, "mcb-rot")
    assert read_info(header, payload).settings.segment_frames == searched.last_encode_stats["segment_frames"]
    assert searched.last_encode_stats["segment_frames"] in sizes
    assert metrics.max_joint_error(slow.positions(), searched.decode(data).positions) <= 0.2
    fast = sinusoidal_motion(num_frames=300, seed=9)
    assert fast.fps >= 60
    assert create("mcb-rot", eps_cm=0.2).encode(fast) == create("mcb-rot", eps_cm=0.2, segment_search=False).encode(fast)


def test_segment_screen_searches_only_the_lengths_whose_screens_come_close(monkeypatch):
    """The screen runs the rate search on the config's length and on at most _SCREENED_SEARCHES others, those whose
    screens (one attempt each) are smallest and within _SCREEN_MARGIN of the best stream so far: with a margin of -1
    (no screen ever close) only the config's length is searched, and each other length costs one attempt."""
    from mocapbench.codecs.mcb_rot.codec import _segment_lengths

    slow = sinusoidal_motion(num_frames=300, seed=9).every(4)
    searches = []
    original = rot_codec.McbRotCodec._search_of

    def counted(prepared, seed=None):
        searches.append(prepared.encoder.config.segment_frames)
        return original(prepared, seed)

    monkeypatch.setattr(rot_codec.McbRotCodec, "_search_of", staticmethod(counted))
    lengths = _segment_lengths(slow.num_frames, 128)
    create("mcb-rot", eps_cm=0.2).encode(slow)
    assert searches[0] == 128 and 1 <= len(searches) <= 1 + rot_codec._SCREENED_SEARCHES
    assert len(set(searches)) == len(searches) and set(searches) <= set(lengths)
    searches.clear()
    monkeypatch.setattr(rot_codec, "_SCREEN_MARGIN", -1.0)
    codec = create("mcb-rot", eps_cm=0.2)
    data = codec.encode(slow)
    assert searches == [128]
    assert metrics.max_joint_error(slow.positions(), codec.decode(data).positions) <= 0.2


def test_rounding_search_keeps_the_smaller_stream_within_the_bound():
    """The rate search also tries wider dead zones at the step it chose: the stream is never larger than without
    that search, its rounding is one of those tried, and it decodes within eps (the closed loop ran on it)."""
    from mocapbench.codecs import container
    from mocapbench.codecs.mcb_rot.stream import read_info

    for seed in range(4):
        motion = sinusoidal_motion(num_frames=150, seed=seed).every(4)
        plain = create("mcb-rot", eps_cm=0.1, rounding_search=False).encode(motion)
        searched = create("mcb-rot", eps_cm=0.1)
        data = searched.encode(motion)
        assert len(data) <= len(plain)
        header, payload = container.unpack(data, "mcb-rot")
        rounding = read_info(header, payload).settings.rounding
        assert any(rounding == np.float32(r) for r in (0.45, 0.40, 0.35))
        if rounding == np.float32(0.45):
            assert data == plain
        assert metrics.max_joint_error(motion.positions(), searched.decode(data).positions) <= 0.1


def test_at_60_fps_and_above_segments_and_chunks_are_at_most_high_rate_segment_frames():
    """At 120 fps the default codes segments and chunks of high_rate_segment_frames (80: the unit a random pose
    entropy-decodes), a config's shorter lengths are kept, 0 keeps the config's; the stream says its lengths and
    decodes within eps. Below 60 fps the limit changes nothing: the same stream as without it."""
    from mocapbench.codecs import container
    from mocapbench.codecs.mcb_rot.stream import read_info

    def lengths(data: bytes) -> tuple[int, int]:
        header, payload = container.unpack(data, "mcb-rot")
        settings = read_info(header, payload).settings
        return settings.segment_frames, settings.chunk_frames

    fast = sinusoidal_motion(num_frames=300, seed=9)
    assert fast.fps == 120
    data = create("mcb-rot", eps_cm=0.2).encode(fast)
    assert lengths(data) == (80, 80)
    assert metrics.max_joint_error(fast.positions(), create("mcb-rot").decode(data).positions) <= 0.2
    assert lengths(create("mcb-rot", eps_cm=0.2, segment_frames=64, chunk_frames=300).encode(fast)) == (64, 80)
    assert lengths(create("mcb-rot", eps_cm=0.2, high_rate_segment_frames=0).encode(fast)) == (128, 128)
    assert lengths(create("mcb-rot", eps_cm=0.2, high_rate_segment_frames=100, chunk_frames=64).encode(fast)) == (
        100, 64)
    slow = fast.every(4)  # 30 fps
    assert (create("mcb-rot", eps_cm=0.2).encode(slow)
            == create("mcb-rot", eps_cm=0.2, high_rate_segment_frames=0).encode(slow))
