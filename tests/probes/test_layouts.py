"""Layouts: known directions on known pixels, exact solid angles, round trips, and one synthetic
environment giving the same SH coefficients in every layout."""

from __future__ import annotations

import numpy as np
import pytest

from shprobe.errors import ShprobeError
from shprobe.probes.env import Env, env_from_function, load_env
from shprobe.probes.layouts import LatLong, detect_layout, get_layout

FOUR_PI = 4.0 * np.pi


def test_latlong_known_directions():
    lay = get_layout("latlong")
    h, w = 64, 128
    xy = lay.direction_to_pixel([[1, 0, 0], [0, 0, -1], [-1, 0, 0], [0, 1, 0], [0, -1, 0]],
                                (h, w))
    np.testing.assert_allclose(xy[:3], [[0.75 * w, h / 2], [0.5 * w, h / 2], [0.25 * w, h / 2]],
                               atol=1e-9)
    assert xy[3, 1] == pytest.approx(0.0) and xy[4, 1] == pytest.approx(h)
    d = lay.pixel_directions((h, w))
    # the pixel right of u = 0.75 on the row below the equator looks nearly along +X
    np.testing.assert_allclose(d[h // 2, 3 * w // 4], [1, 0, 0], atol=np.pi / h)
    assert d[0, 0, 1] > 0.99 and d[-1, 0, 1] < -0.99  # row 0 = +Y


def test_latlong_solid_angles_exact():
    lay = LatLong()
    for h in (1, 3, 64, 513):
        sa = lay.solid_angles((h, 2 * h))
        assert abs(sa.sum() - FOUR_PI) < 1e-9
    # a row's solid angle is the spherical zone area / W (independent closed form)
    h, w = 10, 20
    j = 3
    zone = 2 * np.pi * (np.cos(np.pi * j / h) - np.cos(np.pi * (j + 1) / h))
    assert LatLong.row_solid_angle(h, w)[j] * w == pytest.approx(zone, rel=1e-13)
    # separable helpers rebuild the directions
    d = lay.pixel_directions((h, w))
    cx, cz = LatLong.column_xz(w)
    st = LatLong.row_sin_theta(h)
    np.testing.assert_allclose(d[..., 1], np.repeat(LatLong.row_cos_theta(h)[:, None], w, 1))
    np.testing.assert_allclose(d[..., 0], st[:, None] * cx)
    np.testing.assert_allclose(d[..., 2], st[:, None] * cz)


def test_latlong_round_trip_and_sample():
    lay = LatLong()
    grid = (32, 64)
    d = lay.pixel_directions(grid)
    xy = lay.direction_to_pixel(d, grid)
    jj, ii = np.mgrid[0:32, 0:64] + 0.5
    np.testing.assert_allclose(xy, np.stack([ii, jj], -1), atol=1e-9)
    img = np.random.default_rng(1).random((32, 64, 3)).astype(np.float32)
    np.testing.assert_allclose(lay.sample(img, d), img, atol=1e-5)


def test_detect_layout():
    assert detect_layout((128, 256, 3)) == "latlong"
    assert detect_layout((100, 100)) == "angular"
    for shape in ((300, 400), (400, 300), (50, 300), (300, 50)):
        assert detect_layout(shape) == "cube"
    with pytest.raises(ShprobeError, match="cannot tell"):
        detect_layout((100, 150), "x.hdr")
    with pytest.raises(ShprobeError, match="zero size"):
        detect_layout((0, 0), "x.hdr")


def test_load_env_grace(grace_path):
    env = load_env(grace_path)
    assert env.layout.name == "latlong" and env.grid == (128, 256)
    assert env.radiance.dtype == np.float32 and env.radiance.shape == (128, 256, 3)
    dirs, rad, dw = env.samples()
    assert dirs.shape == (128 * 256, 3) and rad.shape == (128 * 256, 3)
    assert abs(dw.sum() - FOUR_PI) < 1e-9


def test_wrong_aspect_for_requested_layout(grace_path):
    with pytest.raises(ShprobeError, match=r"grace\.hdr") as e:
        load_env(grace_path, layout="angular")
    assert "\n" not in str(e.value)
    with pytest.raises(ShprobeError, match="2:1"):
        Env(np.zeros((10, 10, 3), np.float32), "latlong")


def test_env_from_function_latlong():
    env = env_from_function(lambda d: np.stack([d[..., 0], d[..., 1], d[..., 2]], -1) + 1,
                            "latlong", 16)
    assert env.grid == (16, 32)
    np.testing.assert_allclose(env.radiance, env.directions() + 1, atol=1e-6)


# ----------------------------------------------------------------------------- disc layouts


@pytest.mark.parametrize("name", ["angular", "mirrorball"])
def test_disc_known_directions(name):
    lay = get_layout(name)
    n = 64
    xy = lay.direction_to_pixel([[0, 0, 1], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0]],
                                (n, n))
    # +X at half radius (angular) / sin(45°) (mirror ball) on the right, +Y above the centre
    r = 0.5 if name == "angular" else np.sqrt(0.5)
    c = n / 2
    np.testing.assert_allclose(xy, [[c, c], [c + r * c, c], [c, c - r * c], [c - r * c, c],
                                    [c, c + r * c]], atol=1e-9)
    d = lay.pixel_directions((n, n))
    # the pixels next to the centre look nearly along +Z; right edge middle nearly -Z
    assert d[n // 2, n // 2, 2] > 0.99
    assert d[n // 2, n - 1, 2] < (-0.99 if name == "angular" else -0.9)


def test_angular_rim_is_minus_z_and_outside_invalid():
    lay = get_layout("angular")
    n = 40
    sa = lay.solid_angles((n, n))
    assert sa[0, 0] == 0 and sa[-1, -1] == 0  # corners outside the disc
    d = lay.pixel_directions((n, n))
    assert np.all(d[sa == 0] == 0)
    np.testing.assert_allclose(np.linalg.norm(d[sa > 0], axis=-1), 1.0, atol=1e-12)


@pytest.mark.parametrize("name", ["angular", "mirrorball", "cube"])
@pytest.mark.parametrize("n", [1, 2, 5, 33, 200])
def test_solid_angles_sum_to_4pi(name, n):
    lay = get_layout(name)
    sa = lay.solid_angles(lay.grid_shape(n))
    assert abs(sa.sum() - FOUR_PI) < 1e-6
    assert np.all(sa >= 0)


@pytest.mark.parametrize("n", [20, 21])
@pytest.mark.parametrize("name", ["angular", "mirrorball"])
def test_disc_solid_angles_against_scipy_dblquad(name, n):
    """Independent check: adaptive 2-D quadrature of the Jacobian over pixel ∩ disc (odd n:
    the middle row and column straddle the axes)."""
    from scipy.integrate import dblquad

    lay = get_layout(name)
    sa = lay.solid_angles((n, n))
    h = 2.0 / n
    if name == "angular":
        def jac(y, x):
            r = np.hypot(x, y)
            return np.pi * np.sin(np.pi * r) / r if r > 0 else np.pi ** 2
    else:
        def jac(y, x):
            return 4.0
    # centre, interior, rim pixels (partly covered, centre inside and outside), outside
    for j, i in [(9, 10), (3, 7), (0, 9), (1, 4), (2, 2), (6, 0), (0, 0), (10, 10), (0, 10),
                 (13, 17), (19, 12)]:
        a0, b1 = -1 + h * i, 1 - h * j
        a1, b0 = a0 + h, b1 - h

        def lo(x, b0=b0):
            return max(b0, -np.sqrt(max(1 - x * x, 0.0)))

        def hi(x, b1=b1):
            return min(b1, np.sqrt(max(1 - x * x, 0.0)))

        ref = dblquad(lambda y, x: jac(y, x) if lo(x) < hi(x) else 0.0, max(a0, -1), min(a1, 1),
                      lambda x: min(lo(x), hi(x)), hi, epsabs=1e-13, epsrel=1e-12)[0]
        assert sa[j, i] == pytest.approx(ref, rel=1e-9, abs=1e-13), (j, i)


@pytest.mark.parametrize("name", ["angular", "mirrorball"])
def test_disc_round_trip(name):
    lay = get_layout(name)
    n = 48
    d = lay.pixel_directions((n, n))
    sa = lay.solid_angles((n, n))
    jj, ii = np.mgrid[0:n, 0:n] + 0.5
    centre_in = np.hypot(ii / n * 2 - 1, jj / n * 2 - 1) < 1
    xy = lay.direction_to_pixel(d[centre_in], (n, n))
    np.testing.assert_allclose(xy, np.stack([ii, jj], -1)[centre_in], atol=1e-8)
    # rim pixels whose centre is outside look along their mean direction, which is near −Z;
    # on the angular map (θ linear in r) it maps back into or next to the same pixel
    rim_out = (sa > 0) & ~centre_in
    assert np.all(d[rim_out][:, 2] < -0.9)
    if name == "angular":
        xy = lay.direction_to_pixel(d[rim_out], (n, n))
        assert np.all(np.abs(xy - np.stack([ii, jj], -1)[rim_out]) < 1.0)


# ----------------------------------------------------------------------------- cube maps


def test_cube_known_directions():
    lay = get_layout("cube")
    n = 8
    fxy = lay.direction_to_pixel(np.eye(3).tolist() + (-np.eye(3)).tolist(), (6, n, n))
    np.testing.assert_allclose(fxy, [[0, 4, 4], [2, 4, 4], [4, 4, 4], [1, 4, 4], [3, 4, 4],
                                     [5, 4, 4]])
    # +X face: image right = -Z, image down = -Y (OpenGL orientation)
    d = lay.pixel_directions((6, n, n))
    assert d[0, n // 2, -1, 2] < -0.5 and d[0, -1, n // 2, 1] < -0.5
    assert d[2, 0, n // 2, 2] < -0.5  # +Y face: top edge towards -Z
    assert d[4, n // 2, -1, 0] > 0.5 and d[5, n // 2, -1, 0] < -0.5
    # corner direction (1, 1, 1)/√3 is the +X face's top-left corner
    f, x, y = lay.direction_to_pixel([1.0, 1.0 - 1e-9, 1.0 - 1e-9], (6, n, n))
    assert f == 0 and x == pytest.approx(0, abs=1e-6) and y == pytest.approx(0, abs=1e-6)


def test_cube_solid_angle_closed_form_against_quadrature():
    """Texel solid angle = ∫∫ (1 + a² + b²)^(-3/2) da db (independent Gauss quadrature)."""
    lay = get_layout("cube")
    n = 6
    sa = lay.solid_angles((6, n, n))
    t, w = np.polynomial.legendre.leggauss(20)
    h = 2.0 / n
    for j, i in [(0, 0), (2, 3), (5, 1)]:
        a = -1 + h * (i + (t + 1) / 2)
        b = -1 + h * (j + (t + 1) / 2)
        ref = np.einsum("i,j,ij->", w, w, (1 + a[None] ** 2 + b[:, None] ** 2) ** -1.5) * (
            h / 2) ** 2
        assert sa[3, j, i] == pytest.approx(ref, rel=1e-12)


def test_cube_round_trip_and_files():
    lay = get_layout("cube")
    n = 5
    d = lay.pixel_directions((6, n, n))
    fxy = lay.direction_to_pixel(d, (6, n, n))
    f, jj, ii = np.mgrid[0:6, 0:n, 0:n]
    np.testing.assert_allclose(fxy, np.stack([f, ii + 0.5, jj + 0.5], -1), atol=1e-9)
    faces = np.random.default_rng(3).random((6, n, n, 3)).astype(np.float32)
    np.testing.assert_allclose(lay.sample(faces, d), faces, atol=1e-6)
    for arr, shape in [("hcross", (3 * n, 4 * n)), ("vcross", (4 * n, 3 * n)),
                       ("hstrip", (n, 6 * n)), ("vstrip", (6 * n, n))]:
        img = lay.grid_to_image(faces, arr)
        assert img.shape[:2] == shape and detect_layout(img.shape) == "cube"
        np.testing.assert_array_equal(lay.image_to_grid(img), faces)


def test_cross_edges_are_continuous():
    """In the crosses, neighbouring faces meet along shared cube edges."""
    lay = get_layout("cube")
    n = 16
    d = lay.pixel_directions((6, n, n))
    for arr in ("hcross", "vcross"):
        img = lay.grid_to_image(d, arr)
        if arr == "hcross":  # +Y's bottom row touches +Z's top row; -Z's right wraps to -X
            pairs = [(img[n - 1, n:2 * n], img[n, n:2 * n]),
                     (img[n:2 * n, 4 * n - 1], img[n:2 * n, 0]),
                     (img[2 * n - 1, n:2 * n], img[2 * n, n:2 * n])]
        else:  # -Y's bottom row touches the turned -Z's top row
            pairs = [(img[3 * n - 1, n:2 * n], img[3 * n, n:2 * n]),
                     (img[2 * n - 1, 2 * n:3 * n], img[2 * n, 2 * n:3 * n])][:1]
        for p, q in pairs:
            assert np.all(np.einsum("ic,ic->i", p, q) > np.cos(2.5 * np.pi / 2 / n))


# ----------------------------------------------------------------------------- one environment


_AX = np.array([[0.3, 0.8, -0.5], [-0.7, -0.2, 0.6], [0.5, -0.6, -0.6]])
_AX /= np.linalg.norm(_AX, axis=1, keepdims=True)


def _lobes(d):
    """A smooth test environment: a constant plus one exponential lobe per channel."""
    return 0.2 + np.exp(3.0 * (d @ _AX.T - 1.0)) * np.array([2.0, 1.0, 3.0])


def _project(dirs, values, weights, lmax):
    from shprobe.sh import sh_basis

    return np.einsum("sk,sc,s->kc", sh_basis(dirs, lmax), np.asarray(values, np.float64),
                     weights)


def _reference_coeffs(lmax):
    """Gauss–Legendre in cos θ × uniform φ (exact for this band-limited-enough function)."""
    t, wt = np.polynomial.legendre.leggauss(80)
    phi = 2 * np.pi * np.arange(160) / 160
    st = np.sqrt(1 - t**2)
    d = np.stack([st[:, None] * np.cos(phi), st[:, None] * np.sin(phi),
                  np.broadcast_to(t[:, None], (80, 160))], -1).reshape(-1, 3)
    w = np.repeat(wt * 2 * np.pi / 160, 160)
    return _project(d, _lobes(d), w, lmax)


@pytest.mark.parametrize(("layout", "size", "fname", "arrangement"), [
    ("latlong", 128, "env.exr", None),
    ("angular", 256, "env.exr", None),
    ("mirrorball", 256, "env.pfm", None),
    ("cube", 64, "env.exr", "hcross"),
    ("cube", 64, "env.hdr", "vcross"),
    ("cube", 64, "env.exr", "hstrip"),
    ("cube", 64, "env.pfm", "vstrip"),
])
def test_same_environment_same_coefficients_in_every_layout(tmp_path, layout, size, fname,
                                                            arrangement):
    """Σ L y dω over the valid pixels of each layout, after a write/read round trip, equals the
    reference to 5e-4 of the largest coefficient: the pixel-centre (midpoint) rule errs by
    O(Δ²) with Δ the pixel's angular size (≈ 0.025 rad here for every layout; measured errors
    are 3e-5..1e-4, falling 4× per halving of Δ). RGBE (.hdr) keeps 8 mantissa bits, a
    per-pixel error up to 2⁻⁸ that only partly averages out on a smooth map: 1e-3 there."""
    from shprobe.probes.env import write_env

    lmax = 4
    ref = _reference_coeffs(lmax)
    env = env_from_function(_lobes, layout, size)
    path = tmp_path / fname
    write_env(path, env, arrangement=arrangement or "hcross")
    back = load_env(path, layout="mirrorball" if layout == "mirrorball" else None)
    assert back.layout.name == layout
    assert back.grid == env.grid
    # RGBE keeps 8 mantissa bits of the largest channel (shared exponent)
    tol = 2.0**-7 if fname.endswith(".hdr") else 1e-6
    diff = np.abs(back.radiance - env.radiance).max(-1)
    assert np.all(diff <= tol * env.radiance.max(-1) + 1e-7)
    coeffs = _project(*back.samples(), lmax)
    err = np.abs(coeffs - ref).max() / np.abs(ref).max()
    assert err < (1e-3 if fname.endswith(".hdr") else 5e-4), err


def test_midpoint_error_is_second_order():
    """The tolerance above rests on O(Δ²) convergence: halving the pixel size quarters the
    error (lat-long and angular)."""
    ref = _reference_coeffs(4)
    for layout, n in (("latlong", 32), ("angular", 64)):
        e1, e2 = (np.abs(_project(*env_from_function(_lobes, layout, m).samples(), 4) - ref).max()
                  for m in (n, 2 * n))
        assert 3.0 < e1 / e2 < 5.0


def test_cli_layout_option_and_ldr_warning(tmp_path, capsys):
    import click
    from click.testing import CliRunner

    from shprobe.cli.common import LAYOUT_CHOICES, clamp_option, layout_option
    from shprobe.cli.sources import resolve_coeffs
    from shprobe.probes.images import write_image
    from shprobe.probes.layouts import LAYOUTS

    assert set(LAYOUT_CHOICES) == {"auto", *LAYOUTS}

    @click.command()
    @click.argument("probe")
    @layout_option
    @clamp_option
    def cmd(probe, layout, clamp):
        env = resolve_coeffs(probe, layout=layout, clamp=clamp).env
        click.echo(f"{env.layout.name} {env.grid}")

    write_image(tmp_path / "p.png", np.full((8, 8, 3), 0.5, np.float32))
    res = CliRunner().invoke(cmd, [str(tmp_path / "p.png"), "--layout", "mirrorball"])
    assert res.exit_code == 0 and "mirrorball (8, 8)" in res.output
    assert "warning" in res.output and "not radiance" in res.output
    res = CliRunner().invoke(cmd, [str(tmp_path / "p.png"), "--layout", "bogus"])
    assert res.exit_code != 0


def test_six_face_images(tmp_path):
    from shprobe.probes.images import write_image

    env = env_from_function(_lobes, "cube", 16)
    paths = []
    for k, name in enumerate(("px", "nx", "py", "ny", "pz", "nz")):
        paths.append(tmp_path / f"{name}.pfm")
        write_image(paths[-1], env.radiance[k])
    back = load_env(paths)
    assert back.layout.name == "cube"
    np.testing.assert_array_equal(back.radiance, env.radiance)
    with pytest.raises(ShprobeError, match="6 face images"):
        load_env(paths[:5])
    write_image(tmp_path / "odd.pfm", np.zeros((16, 8, 3), np.float32))
    with pytest.raises(ShprobeError, match=r"odd\.pfm.*square"):
        load_env([*paths[:5], tmp_path / "odd.pfm"])


def test_bad_aspect_and_zero_size(tmp_path):
    from shprobe.probes.images import write_image

    write_image(tmp_path / "wide.exr", np.ones((10, 20, 3), np.float32))
    for lay, what in (("angular", "square"), ("mirrorball", "square"), ("cube", "cross")):
        with pytest.raises(ShprobeError, match=what) as e:
            load_env(tmp_path / "wide.exr", layout=lay)
        assert "wide.exr" in str(e.value) and "\n" not in str(e.value)
    write_image(tmp_path / "odd.exr", np.ones((10, 17, 3), np.float32))
    with pytest.raises(ShprobeError, match=r"odd\.exr: cannot tell the layout"):
        load_env(tmp_path / "odd.exr")
    with pytest.raises(ShprobeError, match="zero size"):
        Env(np.zeros((0, 0, 3), np.float32), "latlong")


def test_env_rotated_matches_the_wigner_rotation_of_its_coefficients():
    """Turning the map by resampling (Env.rotated) and turning its SH coefficients by the
    library's Wigner rotation agree to the resampling error."""
    from shprobe.lighting import project
    from shprobe.sh.rotation import from_axis_angle, rotate

    env = env_from_function(lambda d: 1.0 + np.stack([d[..., 0], d[..., 1] ** 2, d[..., 2]],
                                                     -1) * 0.5, "latlong", 128)
    R = from_axis_angle([1.0, 2.0, 3.0], 37.0)
    got = project(env.rotated(R), 2)
    want = rotate(project(env, 2), R)
    np.testing.assert_allclose(got, want, atol=2e-3 * np.abs(want).max())
