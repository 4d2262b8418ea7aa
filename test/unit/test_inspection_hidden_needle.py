"""A needle hidden by an object is never read confidently (issue #40, "seeing what is not there"):
the simulated yard's dials painted frontally, a bird's nest (sim.faces.paint_foreign) over the
needle's outer part; before, some of these read confidently wrong (the oil thermometer 114.7 C for
76 C at confidence 96, its hidden needle taken for the nest's edge). The clean dials still read
confidently, their needle seen along its whole length. Read as a patrol reads them: with the needle
model learned at calibration (the oil thermometer's drag pointer stays in view when its needle is
hidden: the line fit takes the drag pointer, the model says it is not this meter's needle)."""
import os

import numpy as np
import pytest

from inspection_robot.inspection.pointer import HIDDEN_BELOW, PointerReader
from inspection_robot.sim.world import World
from inspection_robot_testing.world_views import cover_with_nest, painted_dial

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
FACES = ("transformer_1/winding_temp", "transformer_1/oil_temp", "cabinet_1/voltmeter", "cabinet_1/ammeter")


@pytest.fixture(scope="module")
def world():
    return World.load(os.path.join(ROOT, "config", "sim_world.yaml"))


def read(face, value, cover, model=None):
    """The face at ``value`` painted at 400 px, a nest of ``cover`` dial radii's half-side centred on the
    needle at 0.6 of its radius (0: none), read with its calibration and needle ``model``; (reading,
    scale). ``model`` "learn": learns it there (the calibration picture) and returns it as the reading."""
    image, quad, scale, centre, radius, aspect = painted_dial(face, value)
    if cover:
        h, w = image.shape[:2]
        angle = np.radians(face.needle_angle_deg(value))
        r = radius * w
        cover_with_nest(image, centre[0] * w + 0.6 * r * np.sin(angle), centre[1] * h - 0.6 * r * np.cos(angle),
                        int(cover * r), seed=7)
    dial = (centre, radius, aspect)
    if model == "learn":
        return PointerReader().learn(image, quad, scale, value, *dial), scale
    return PointerReader().read(image, quad, scale, *dial, model=model), scale


@pytest.mark.parametrize("face_id", FACES)
def test_a_hidden_needle_is_uncertain_with_the_reason_and_a_clear_one_is_not(world, face_id):
    face = world.faces[face_id]
    state = face.value
    low, high = face.range
    try:
        model, _ = read(face, low + 0.4 * (high - low), 0.0, "learn")     # calibrated as a patrol reads it
        for share in (0.1, 0.5, 0.9):
            value = low + share * (high - low)
            clean, scale = read(face, value, 0.0, model)
            assert scale.error_percent_fs(clean.value, value) < 1.0 and clean.confidence >= 80, clean
            assert clean.detail["needle_visible"] >= 0.75 and "hidden" not in clean.detail["reason"], clean
            for cover in (0.35, 0.6):
                hidden, _ = read(face, value, cover, model)
                assert hidden.confidence < 50, (value, cover, hidden)
                if face.drag is not None:
                    # the drag pointer is in plain view: the line fit takes it, the needle model does not
                    assert "this meter's needle " in hidden.detail["reason"], (value, cover, hidden.detail)
                    continue
                assert hidden.detail["needle_visible"] < HIDDEN_BELOW, (value, cover, hidden.detail)
                assert "needle hidden: " in hidden.detail["reason"] and "% of its length not visible" in \
                    hidden.detail["reason"], hidden.detail["reason"]
    finally:
        face.set_value(state)
