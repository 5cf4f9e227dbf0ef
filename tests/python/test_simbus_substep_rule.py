"""The substep rule in the Python package: settings take
`substep_rule="refuse" | "clamp" | "stretch"` and report it, a 0.2 s step
with the default substepping is refused naming the rule, and under "clamp"
(CARLA's) each frame says physics was clamped and by how much."""

import pytest

import simbus

from simbus_support import server  # noqa: F401 (a fixture)


def frame_from(client, frame_id):
    """The first frame this client sees at or after `frame_id` (the world
    runs asynchronously, so a reader may skip frames)."""
    while True:
        with client.wait_for_frame(timeout=10) as frame:
            if frame.frame >= frame_id:
                return frame.copy()


def test_settings_take_and_report_the_substep_rule(server):
    client = server("--scene", "empty").client()
    assert client.settings().substep_rule == "refuse"
    with pytest.raises(simbus.SettingsError, match="substep rule 'refuse'; 'clamp' runs CARLA's way"):
        client.apply_settings(fixed_delta_seconds=0.2)
    with pytest.raises(ValueError, match="'bend' is not a substep rule: refuse, clamp or stretch"):
        client.apply_settings(fixed_delta_seconds=0.2, substep_rule="bend")
    assert client.settings().fixed_delta_seconds is None, "refused settings change nothing"

    first = client.apply_settings(fixed_delta_seconds=0.2, substep_rule="clamp")
    settings = client.settings()
    assert settings.substep_rule == "clamp"
    assert "substep_rule='clamp'" in repr(settings)
    frame = frame_from(client, first)
    assert frame.delta_seconds == 0.2
    assert frame.physics_clamped
    assert frame.physics_seconds == 0.1

    first = client.apply_settings(substep_rule="stretch")
    assert client.settings().substep_rule == "stretch"
    frame = frame_from(client, first)
    assert not frame.physics_clamped
    assert frame.physics_seconds == 0.2
