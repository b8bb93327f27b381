"""Fitting one map onto another from matched points (serveur.maps.align, pure)."""

from __future__ import annotations

import math
import random

import pytest

from serveur.errors import InvalidField
from serveur.maps.align import Similarity, fit


def test_a_rotated_scaled_shifted_copy_is_recovered() -> None:
    truth = Similarity(1.07, math.radians(23.0), 3.5, -1.25)
    src = [(0.0, 0.0), (12.0, 0.0), (12.0, 9.0), (0.0, 9.0), (6.0, 4.5)]
    dst = [truth.apply(*p) for p in src]
    got = fit(src, dst)
    assert got.scale == pytest.approx(1.07)
    assert math.degrees(got.rotation) == pytest.approx(23.0)
    assert (got.tx, got.ty) == pytest.approx((3.5, -1.25))
    assert got.rms < 1e-9


def test_two_pairs_fix_it_exactly() -> None:
    truth = Similarity(0.5, -2.0, -4.0, 7.0)
    src = [(1.0, 2.0), (9.0, -3.0)]
    got = fit(src, [truth.apply(*p) for p in src])
    assert (got.scale, got.rotation, got.tx, got.ty) == pytest.approx((0.5, -2.0, -4.0, 7.0))


def test_a_mis_clicked_point_stands_out_in_its_residual() -> None:
    truth = Similarity(1.0, 0.3, 1.0, 2.0)
    rng = random.Random(4)
    src = [(rng.uniform(0, 15), rng.uniform(0, 10)) for _ in range(6)]
    dst = [truth.apply(*p) for p in src]
    dst[2] = (dst[2][0] + 1.5, dst[2][1])  # clicked a metre and a half off
    got = fit(src, dst)
    worst = max(range(6), key=lambda i: got.residuals[i])
    assert worst == 2 and got.rms > 0.3


def test_noise_of_a_few_centimetres_fits_within_it() -> None:
    truth = Similarity(1.02, 1.1, -3.0, 4.0)
    rng = random.Random(7)
    src = [(rng.uniform(0, 15), rng.uniform(0, 10)) for _ in range(8)]
    dst = [
        (x + rng.gauss(0, 0.03), y + rng.gauss(0, 0.03))
        for x, y in map(lambda p: truth.apply(*p), src)
    ]
    got = fit(src, dst)
    assert got.scale == pytest.approx(1.02, abs=0.01)
    assert got.rotation == pytest.approx(1.1, abs=0.01)
    assert got.rms < 0.06


def test_the_inverse_takes_points_back() -> None:
    t = Similarity(1.3, 0.7, 2.0, -5.0)
    x, y = t.inverse().apply(*t.apply(4.0, 6.0))
    assert (x, y) == pytest.approx((4.0, 6.0))
    assert t.apply_yaw(math.pi) == pytest.approx(math.remainder(math.pi + 0.7, math.tau))


@pytest.mark.parametrize(
    ("src", "dst", "words"),
    [
        ([(0.0, 0.0)], [(1.0, 1.0)], "at least two"),
        ([(0.0, 0.0), (5.0, 0.0)], [(1.0, 1.0)], "its match"),
        ([(0.0, 0.0), (0.1, 0.0)], [(1.0, 1.0), (1.1, 1.0)], "too close"),
        ([(0.0, 0.0), (math.nan, 0.0)], [(1.0, 1.0), (3.0, 1.0)], "not a number"),
    ],
)
def test_points_that_cannot_fit_are_refused(src: list, dst: list, words: str) -> None:
    with pytest.raises(InvalidField, match=words):
        fit(src, dst)
