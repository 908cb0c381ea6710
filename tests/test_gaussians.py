"""GaussianSet: PLY round trip, activations, packing and clear errors for bad input."""
import numpy as np
from numpy.lib.recfunctions import repack_fields
import pytest

from glint_mi import conventions as cv
from glint_mi.model.gaussians import GaussianDataError, GaussianSet


def _set(rng, n=50, deg=2):
    k = (deg + 1) ** 2
    return GaussianSet(rng.normal(size=(n, 3)), rng.normal(-3, 1, (n, 3)), rng.normal(size=(n, 4)), rng.normal(size=n),
                       rng.normal(size=(n, k, 3)), rng.normal(size=n), rng.normal(size=n))


def test_ply_round_trip_is_exact(tmp_path, rng):
    g = _set(rng)
    g.save_ply(tmp_path / "a.ply")
    h = GaussianSet.load_ply(tmp_path / "a.ply")
    g.normals = rng.normal(size=(len(g), 3)).astype(np.float32)  # a normal attribute of their own (nx, ny, nz)
    g.save_ply(tmp_path / "a.ply")
    h = GaussianSet.load_ply(tmp_path / "a.ply")
    for name in ("means", "log_scales", "quats_wxyz", "logit_opacity", "sh", "logit_specular", "logit_transparency",
                 "normals"):
        np.testing.assert_array_equal(getattr(g, name), getattr(h, name), err_msg=name)
    h.save_ply(tmp_path / "b.ply")
    assert (tmp_path / "a.ply").read_bytes() == (tmp_path / "b.ply").read_bytes()


def test_ply_is_standard_3dgs_layout(tmp_path, rng):
    from plyfile import PlyData
    g = _set(rng, deg=1)
    g.save_ply(tmp_path / "a.ply")
    names = PlyData.read(str(tmp_path / "a.ply"))["vertex"].data.dtype.names
    assert names[:9] == ("x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2")
    # the standard fields at their usual offsets (viewers read them so), GLINT's extras after them
    k = names.index("opacity")
    assert names[k:k + 8] == ("opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3")
    assert names[k + 8:] == ("specular", "transparency")
    # f_rest is channel-major in 3DGS files: f_rest_0..2 are the red coefficients 1..3
    rest = PlyData.read(str(tmp_path / "a.ply"))["vertex"]
    np.testing.assert_array_equal(rest["f_rest_1"], g.sh[:, 2, 0])
    np.testing.assert_array_equal(rest["f_rest_3"], g.sh[:, 1, 1])


def test_normals_default_to_the_surfels_axis_and_zero_file_normals_are_derived(tmp_path, rng):
    """Without a normal attribute a set's normals are its rotations' z axes (a surfel's normal, R(q) e_z); a 3DGS
    file's zero nx, ny, nz are derived the same way, a given one is kept; a zero-length normal given in memory is
    refused, naming the field."""
    from plyfile import PlyData, PlyElement
    g = _set(rng, deg=0)
    q = g.quats_wxyz.astype(np.float64)  # the COLMAP readers' own (w, x, y, z) matrix, an independent reference
    R = np.stack([cv.qvec_to_rotmat(qi / np.linalg.norm(qi)) for qi in q])
    np.testing.assert_allclose(g.normals, R[:, :, 2], atol=1e-6)
    g.save_ply(tmp_path / "a.ply")
    v = PlyData.read(str(tmp_path / "a.ply"))["vertex"].data.copy()
    for c in ("nx", "ny", "nz"):
        v[c][:10] = 0.0  # as 3DGS writes them
    v["nx"][10:] = 7.0
    PlyData([PlyElement.describe(v, "vertex")]).write(str(tmp_path / "b.ply"))
    h = GaussianSet.load_ply(tmp_path / "b.ply")
    np.testing.assert_allclose(h.normals[:10], R[:10, :, 2], atol=1e-6)
    np.testing.assert_array_equal(h.normals[10:, 0], 7.0)
    g.normals[3] = 0.0
    with pytest.raises(GaussianDataError, match="'normals'.*Gaussian 3"):
        g.validate()


def test_ply_without_extras_gets_paper_inits(tmp_path, rng):
    from plyfile import PlyData, PlyElement
    g = _set(rng, deg=0)
    g.save_ply(tmp_path / "a.ply")
    v = PlyData.read(str(tmp_path / "a.ply"))["vertex"].data
    keep = [n for n in v.dtype.names if n not in ("specular", "transparency")]
    PlyData([PlyElement.describe(repack_fields(v[keep]), "vertex")]).write(str(tmp_path / "b.ply"))
    h = GaussianSet.load_ply(tmp_path / "b.ply")
    np.testing.assert_allclose(cv.sigmoid(h.logit_specular), 1e-3, rtol=1e-4)
    np.testing.assert_allclose(cv.sigmoid(h.logit_transparency), 0.01, rtol=1e-4)


def test_ply_missing_field_error_names_file_and_field(tmp_path, rng):
    from plyfile import PlyData, PlyElement
    g = _set(rng, deg=0)
    g.save_ply(tmp_path / "a.ply")
    v = PlyData.read(str(tmp_path / "a.ply"))["vertex"].data
    keep = [n for n in v.dtype.names if n != "scale_1"]
    PlyData([PlyElement.describe(repack_fields(v[keep]), "vertex")]).write(str(tmp_path / "bad.ply"))
    with pytest.raises(GaussianDataError, match=r"bad\.ply.*scale_1"):
        GaussianSet.load_ply(tmp_path / "bad.ply")


def test_bad_shapes_and_nan_are_refused(rng):
    g = _set(rng, n=5)
    with pytest.raises(GaussianDataError, match="log_scales.*expected \\(5, 3\\)"):
        GaussianSet(g.means, g.log_scales[:4], g.quats_wxyz, g.logit_opacity, g.sh, g.logit_specular, g.logit_transparency)
    means = g.means.copy()
    means[3, 1] = np.nan
    with pytest.raises(GaussianDataError, match="'means' has NaN.*Gaussian 3"):
        GaussianSet(means, g.log_scales, g.quats_wxyz, g.logit_opacity, g.sh, g.logit_specular, g.logit_transparency)
    with pytest.raises(ValueError, match="SH values"):
        GaussianSet(g.means, g.log_scales, g.quats_wxyz, g.logit_opacity, np.zeros((5, 2, 3)), g.logit_specular, g.logit_transparency)


def test_quaternion_orders_and_degenerate_quaternions():
    q = np.array([[1.0, 2.0, 3.0, 4.0]])
    np.testing.assert_array_equal(cv.xyzw_to_wxyz(cv.wxyz_to_xyzw(q)), q)
    np.testing.assert_array_equal(cv.wxyz_to_xyzw(np.array([[1.0, 0, 0, 0]])), [[0, 0, 0, 1.0]])
    n = cv.normalize_quaternions_xyzw(np.array([[0.0, 0, 0, 0], [0, 0, 0, 2]]))
    np.testing.assert_array_equal(n, [[0, 0, 0, 1], [0, 0, 0, 1]])


def test_mitsuba_packing_round_trip_and_shell(rng):
    g = _set(rng, deg=1)
    a = g.to_mitsuba("ellipsoid", min_shell_ratio=0.3, opacity_shells=False)
    assert a["data"].shape == (50, 10) and a["sh_coeffs"].shape == (50, 12)
    shell = a["data"][:, 3:6]
    assert np.all(shell >= 0.3 * shell.max(axis=1, keepdims=True) * (1 - 1e-6))
    assert np.all(shell >= a["kernel_scales"] * (1 - 1e-6))
    # opacity shells: scaled by sqrt(E^2 + 2 ln o) / E, so that o exp(-r^2 / 2) at the shell = exp(-E^2 / 2)
    E = 1.5
    o = cv.sigmoid(g.logit_opacity)
    small = g.to_mitsuba("ellipsoid", min_shell_ratio=0.3, extent=E)["data"][:, 3:6].astype(np.float64)
    r = small[:, 0] / shell[:, 0] * E
    live = o > np.exp(-E * E / 2)
    assert live.any() and (~live).any(), "the set should hold Gaussians on both sides of the cut-off"
    np.testing.assert_allclose(o[live] * np.exp(-0.5 * r[live] ** 2), np.exp(-E * E / 2), rtol=1e-4)
    np.testing.assert_allclose(small[~live], 1e-3 * shell[~live], rtol=1e-5)  # never reaches it: a tiny shell
    h = GaussianSet.from_mitsuba(a, kernel="ellipsoid")
    np.testing.assert_allclose(h.log_scales, g.log_scales, atol=2e-5)
    np.testing.assert_allclose(cv.sigmoid(h.logit_opacity), cv.sigmoid(g.logit_opacity), atol=1e-6)
    s = g.to_mitsuba("surfel", opacity_shells=False)  # the thin axis is kept (round trip) but the shell only follows the in-plane axes
    np.testing.assert_allclose(s["kernel_scales"], np.exp(g.log_scales), rtol=1e-6)
    assert np.all(s["data"][:, 5] >= 0.3 * s["kernel_scales"][:, :2].max(1) * (1 - 1e-6))


def test_srgb_transfer_round_trip():
    x = np.linspace(0, 1, 1001)
    np.testing.assert_allclose(cv.linear_to_srgb(cv.srgb_to_linear(x)), x, atol=1e-12)
    assert abs(cv.linear_to_srgb(0.18) - 0.4613561295) < 1e-9  # 18 % grey is ~118/255 in sRGB
