"""Direction sets: unit length, reproducible, unbiased, and converging at the expected rates."""

import numpy as np
import pytest

from prt_addon.core.sh import analytic, basis as sh, directions


@pytest.mark.parametrize("kind", directions.KINDS)
def test_unit_reproducible_and_seeded(kind):
    a = directions.make_directions(kind, 500, seed=3)
    b = directions.make_directions(kind, 500, seed=3)
    c = directions.make_directions(kind, 500, seed=4)
    assert a.directions.shape == (500, 3)
    np.testing.assert_allclose(np.linalg.norm(a.directions, axis=1), 1.0, atol=1e-14)
    np.testing.assert_array_equal(a.directions, b.directions)
    assert not np.allclose(a.directions, c.directions)
    assert a.weight == pytest.approx(4 * np.pi / 500)


@pytest.mark.parametrize("kind", directions.KINDS)
def test_basis_table_is_the_basis_at_the_directions(kind):
    ds = directions.make_directions(kind, 300, seed=1)
    np.testing.assert_array_equal(ds.basis(5), sh.sh_basis(ds.directions, 5))
    np.testing.assert_array_equal(ds.basis(3), sh.sh_basis(ds.directions, 3))  # sliced from the cache


def test_stratified_has_one_point_per_equal_area_cell():
    """Every z-row holds counts differing by <= 1 and each row's z-extent is 2*count/N."""
    count = 1000
    d = directions.make_directions("STRATIFIED", count, seed=0).directions
    rows = int(round(np.sqrt(count / 2)))
    per_row = np.full(rows, count // rows)
    per_row[: count % rows] += 1
    z_edges = 1 - 2 * np.concatenate([[0], np.cumsum(per_row)]) / count
    hist = np.histogram(-d[:, 2], bins=-z_edges)[0]
    np.testing.assert_array_equal(hist, per_row)


def quadrature_error(kind, count, seeds, order=6):
    """RMS error over seeds of integrating the clamped cosine about a fixed normal."""
    normal = np.array([0.2, -0.4, 0.89])
    normal /= np.linalg.norm(normal)
    exact = analytic.clamped_cosine_coeffs(order, normal)
    errors = []
    for seed in seeds:
        ds = directions.make_directions(kind, count, seed=seed)
        t = ds.weight * ds.basis(order).T @ (np.maximum(0, ds.directions @ normal) / np.pi)
        errors.append(np.sqrt(np.mean((t - exact) ** 2)))
    return np.sqrt(np.mean(np.square(errors)))


def test_every_set_is_unbiased_and_converges():
    for kind in directions.KINDS:
        coarse = quadrature_error(kind, 256, range(8))
        fine = quadrature_error(kind, 4096, range(8))
        assert fine < coarse / 3.0, kind  # 16x the points: at least the Monte-Carlo sqrt(16) = 4, minus noise
    # Fibonacci (and stratification) beat i.i.d. points at equal count.
    assert quadrature_error("FIBONACCI", 1024, range(8)) < quadrature_error("UNIFORM", 1024, range(8)) / 3.0
    assert quadrature_error("STRATIFIED", 1024, range(8)) < quadrature_error("UNIFORM", 1024, range(8)) / 3.0


def test_bad_arguments():
    with pytest.raises(ValueError, match="kind"):
        directions.make_directions("HALTON", 10)
    with pytest.raises(ValueError, match="count"):
        directions.make_directions("FIBONACCI", 0)
