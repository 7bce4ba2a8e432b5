"""The comparison interpolants against independent implementations (scipy, NumPy)."""

import numpy as np
import pytest
from scipy.interpolate import LinearNDInterpolator, RBFInterpolator

import inkwarp


def random_samples(n, shape, seed):
    rng = np.random.default_rng(seed)
    h, w = shape
    points = np.column_stack([rng.uniform(0, w - 1, n), rng.uniform(0, h - 1, n)])
    return points, rng.normal(0, 4, (n, 2))


def pixel_grid(shape):
    h, w = shape
    ys, xs = np.mgrid[0:h, 0:w]
    return np.column_stack([xs.ravel(), ys.ravel()]).astype(float)


@pytest.mark.parametrize("n, seed", [(5, 0), (40, 1), (300, 2)])
def test_tps_exact_matches_scipy_thin_plate_rbf(n, seed):
    shape = (37, 53)
    points, disp = random_samples(n, shape, seed)
    ours = inkwarp.interpolate(points, disp, shape, method="tps-exact")
    oracle = RBFInterpolator(points, disp, kernel="thin_plate_spline", degree=1)(pixel_grid(shape))
    np.testing.assert_allclose(ours.reshape(-1, 2), oracle, atol=2e-4)


def test_tps_exact_reproduces_an_affine_field():
    shape = (40, 60)
    points, _ = random_samples(30, shape, 5)
    m = np.array([[0.1, -0.3], [0.25, 0.05]])
    ours = inkwarp.interpolate(points, points @ m.T + [2.0, -1.0], shape, method="tps-exact")
    want = pixel_grid(shape) @ m.T + [2.0, -1.0]
    np.testing.assert_allclose(ours.reshape(-1, 2), want, atol=1e-4)


def test_tps_exact_thinning_keeps_what_it_fits_exact():
    shape = (64, 64)
    points, disp = random_samples(400, shape, 9)
    field, report = inkwarp.interpolate_report(points, disp, shape, method="tps-exact", max_samples=50)
    assert report["samples_used"] == 50 and report["samples_given"] == 400
    assert "farthest-point" in report["notes"][0]
    # Deterministic: the samples' order does not matter.
    again = inkwarp.interpolate(points[::-1], disp[::-1], shape, method="tps-exact", max_samples=50)
    np.testing.assert_array_equal(field, again)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_triangulation_matches_qhull_linear_interpolation(seed):
    shape = (41, 57)
    h, w = shape
    points, disp = random_samples(25, shape, seed)
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], float)
    oracle = LinearNDInterpolator(np.vstack([points, corners]), np.vstack([disp, np.zeros((4, 2))]))
    want = oracle(pixel_grid(shape))
    ours = inkwarp.interpolate(points, disp, shape, method="triangulation").reshape(-1, 2)
    np.testing.assert_allclose(ours, want, atol=1e-4)


def beier_neely_reference(points, disp, rest, pose, shape, a=1.0, b=2.0, p=0.0):
    """Beier & Neely (forward, with Shepard points) written out in NumPy."""
    X = pixel_grid(shape)
    num = np.zeros_like(X)
    den = np.zeros(len(X))
    for (P, Q), (P2, Q2) in zip(rest, pose):
        d, d2 = Q - P, Q2 - P2
        perp = lambda v: np.array([-v[1], v[0]])  # noqa: E731
        r = X - P
        u = r @ d / (d @ d)
        v = r @ perp(d) / np.linalg.norm(d)
        Xp = P2 + u[:, None] * d2 + v[:, None] * perp(d2) / np.linalg.norm(d2)
        dist = np.where(u < 0, np.linalg.norm(X - P, axis=1),
                        np.where(u > 1, np.linalg.norm(X - Q, axis=1), np.abs(v)))
        wgt = (np.linalg.norm(d) ** p / (a + dist)) ** b
        num += wgt[:, None] * (Xp - X)
        den += wgt
    for q, dq in zip(points, disp):
        wgt = (1.0 / (a + np.linalg.norm(X - q, axis=1))) ** b
        num += wgt[:, None] * dq
        den += wgt
    return num / den[:, None]


@pytest.mark.parametrize("a, b, p", [(1.0, 2.0, 0.5), (0.3, 1.0, 0.0), (4.0, 1.5, 1.0)])
def test_beier_neely_matches_a_numpy_reference(a, b, p):
    shape = (30, 45)
    rng = np.random.default_rng(4)
    rest = rng.uniform(0, 30, (4, 2, 2))
    pose = rest + rng.normal(0, 3, (4, 2, 2))
    points, disp = random_samples(3, shape, 8)
    ours = inkwarp.interpolate(points, disp, shape, method="beier-neely", lines=(rest, pose), a=a, b=b, p=p)
    want = beier_neely_reference(points, disp, rest, pose, shape, a, b, p)
    np.testing.assert_allclose(ours.reshape(-1, 2), want, atol=1e-4)


def test_beier_neely_single_line_pair_is_rigid():
    theta = 0.4
    rot = np.array([[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]])
    rest = np.array([[[5.0, 8.0], [20.0, 14.0]]])
    pose = rest @ rot.T + [3.0, -2.0]
    shape = (25, 30)
    field = inkwarp.interpolate(np.zeros((0, 2)), np.zeros((0, 2)), shape, method="beier-neely",
                                lines=(rest, pose))
    X = pixel_grid(shape)
    np.testing.assert_allclose(field.reshape(-1, 2), X @ rot.T + [3.0, -2.0] - X, atol=1e-4)


def test_thin_plate_map_reproduces_affine_maps():
    rng = np.random.default_rng(3)
    src = rng.uniform(0, 100, (12, 2))
    m = np.array([[1.2, 0.3], [-0.2, 0.9]])
    w = inkwarp.ThinPlateMap(src, src @ m.T + [5.0, 7.0])
    probe = rng.uniform(-50, 150, (20, 2))
    np.testing.assert_allclose(w(probe), probe @ m.T + [5.0, 7.0], atol=1e-8)
    assert len(w) == 12


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"method": "bicubic"}, 'unknown method "bicubic"'),
        ({"points": [[1.0, 2.0, 3.0]]}, r"points must be an \(N, 2\) array"),
        ({"points": [[np.nan, 1.0]]}, r"points\[0\] is not finite"),
        ({"displacements": [[1.0, 1.0], [0.0, 0.0]]}, "same length"),
        ({"shape": (0, 5)}, "at least"),
        ({"method": "beier-neely", "a": 0.0}, "a must be a number above 0 and at most 1e6; got 0.0"),
        ({"max_samples": 0}, "max_samples must be a whole number from 1 to 4294967295"),
        # Each named, with its range (they were bare TypeErrors and OverflowErrors, or "2" taken as 2).
        ({"method": "beier-neely", "a": None}, "a must be a number above 0"),
        ({"method": "beier-neely", "p": [1]}, "p must be a number from 0 to 16"),
        ({"method": "beier-neely", "p": 10**400}, "p must be a number from 0 to 16"),
        ({"method": "beier-neely", "b": "2"}, "b must be a number from 0 to 16; got '2'"),
        ({"max_samples": 10**30}, "max_samples must be a whole number from 1 to 4294967295"),
        ({"lines": ([[[0, 0], [1, 1]]], [])}, "the rest and pose segments must match"),
    ],
)
def test_bad_arguments_raise_value_error(kwargs, message):
    args = {"points": [[1.0, 1.0]], "displacements": [[1.0, 0.0]], "shape": (4, 4)} | kwargs
    points, displacements, shape = args.pop("points"), args.pop("displacements"), args.pop("shape")
    with pytest.raises(ValueError, match=message):
        inkwarp.interpolate(points, displacements, shape, **args)


def test_no_samples():
    none = np.zeros((0, 2))
    assert not inkwarp.interpolate(none, none, (3, 3), method="tps-exact").any()
    assert not inkwarp.interpolate(none, none, (3, 3), method="triangulation").any()
    with pytest.raises(ValueError, match="needs at least one point or line pair"):
        inkwarp.interpolate(none, none, (3, 3), method="beier-neely")


def test_the_tps_report_gives_its_seconds():
    # It gave NaN, where the other methods give the time taken.
    _, report = inkwarp.interpolate_report([[4, 4], [40, 4], [20, 25]], [[1, 0], [0, 1], [2, 2]], (32, 48), method="tps")
    assert 0 < report["seconds"] < 60


def test_lines_that_are_not_numbers_are_named():
    # numpy's "could not convert string to float: np.str_('a')" named neither the argument nor the fix.
    args = ([[1, 1], [5, 5], [9, 1]], [[0, 0], [1, 1], [0, 1]], (12, 12))
    with pytest.raises(ValueError, match=r"^lines must be a pair \(rest, pose\)"):
        inkwarp.interpolate(*args, method="beier-neely", lines="ab")
    with pytest.raises(ValueError, match=r"^lines\[0\] \(rest\) must be an \(L, 2, 2\) array of numbers"):
        inkwarp.interpolate(*args, method="beier-neely", lines=("ab", "cd"))
