"""The suite's photometric families (bench/suite/photometric.py): the tune-side noise family sensor_noise (task
lownoise) is a tune family, disjoint from the report families, and matches low light's noise over the frame's range
without its darkening."""

from __future__ import annotations

import numpy as np
import pytest

from bench.suite import photometric


def test_tune_and_report_families_are_disjoint_and_sensor_noise_is_tuned_on() -> None:
    assert "sensor_noise" in photometric.TUNE_FAMILIES
    assert "low_light" in photometric.REPORT_FAMILIES
    assert not set(photometric.TUNE_FAMILIES) & set(photometric.REPORT_FAMILIES)
    assert {v.label for v in photometric.variants("tune", rgb=False)} >= {"sensor_noise/sigma 3.5",
                                                                           "sensor_noise/sigma 10"}
    assert not any(v.family == "sensor_noise" for v in photometric.variants("report", rgb=False))


@pytest.mark.parametrize(("noise", "light"), [(0, 0), (1, 1)])
def test_sensor_noise_matches_low_lights_noise_over_the_range(noise: int, light: int) -> None:
    """Each sensor_noise variant's noise std over the frame's range is within 10 % of the low_light variant's (its
    std over its gain), its mean grey value is the frame's (gain 1), and it is 8-bit."""
    x = np.full((200, 200), 0.5)
    sn, ll = photometric.FAMILIES["sensor_noise"][noise], photometric.FAMILIES["low_light"][light]
    a, b = sn(x, 3), ll(x, 3)
    gain = ll.change.keywords["gain"]
    assert np.std(a) == pytest.approx(np.std(b) / gain, rel=0.1)
    assert np.mean(a) == pytest.approx(0.5, abs=0.005)
    assert np.array_equal(np.rint(a * 255.0) / 255.0, a)
    assert not np.array_equal(a, sn(x, 4))  # the seed draws the noise
