"""The crowd bench's stage measures (humv_usd.bench.crowd): foot slip on hand-made tracks whose
answer is known in closed form."""

import numpy as np

from humv_usd.bench.crowd import CONTACT_TOL_M, _stance_slip


def _track(frames: int, points: int) -> tuple[np.ndarray, np.ndarray]:
    return np.zeros((frames, points, 2)), np.full((frames, points), 0.05)


def test_a_planted_point_that_slides_reports_its_travel():
    xy, h = _track(10, 3)
    h[2:8, 0] = 0.0  # point 0 touches for frames 2..7 and slides 4 mm per frame along x
    xy[2:8, 0, 0] = 0.004 * np.arange(6)
    assert np.isclose(_stance_slip(xy, h, CONTACT_TOL_M), 0.020)


def test_motion_off_the_ground_and_between_contacts_is_not_slip():
    xy, h = _track(12, 2)
    h[0:4, 0] = 0.0  # touches, lifts (moves 30 cm in the air), touches again elsewhere
    h[8:12, 0] = 0.0
    xy[4:, 0, 0] = 0.30
    # point 1 moves 5 cm while 4 mm up (a swinging foot passing the ground, s7): not touching
    h[0:4, 1] = 0.004
    xy[0:4, 1, 1] = np.linspace(0.0, 0.05, 4)
    assert _stance_slip(xy, h, CONTACT_TOL_M) == 0.0
