"""The runtime benchmark's ``--set``: an mcb-rot field it cannot take is a usage line (exit 2) before anything is
built or encoded, never a traceback after minutes of encoding."""

from __future__ import annotations

import pytest

from mocapbench.benchmarks import runtime


@pytest.mark.parametrize("pair, message", [
    ("segment_frames", "expects key=value"),
    ("no_such_field=3", "Unknown parameter"),
    ("segment_frames=0", "segment_frames"),
    ("eps_cm=0.5", "--eps"),
])
def test_a_setting_it_cannot_take_is_one_usage_line(monkeypatch, capsys, pair, message):
    monkeypatch.setattr(runtime, "build_harness", lambda: pytest.fail("built before the settings were checked"))
    with pytest.raises(SystemExit) as exit_info:
        runtime.main(["--set", pair])
    assert exit_info.value.code == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert message in error[-1] and "Traceback" not in "\n".join(error)
