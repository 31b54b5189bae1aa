"""The camera's depth-resolution map (lf_flame.tomo.resolution) and ``lf-flame resolution``:
the responses are the exact operator's spectra, the pairs' condition numbers are their
normal blocks', the map behaves as parallax says, the paper's rule of thumb, the command on
two cameras and its refusals."""
import dataclasses
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from lf_flame.cli import main
from lf_flame.optics.camera import PAPER_CAMERA, PlenopticCamera
from lf_flame.tomo.exact import ExactOperator
from lf_flame.tomo.quadrature import exact_kernels
from lf_flame.tomo.conditioning import kernel_response, normal_matrix, pair_conditions
from lf_flame.tomo.resolution import (
    FEATURE_SIZES_MM,
    depth_resolution,
    resolution_from_kernels,
    stack_depths,
)

#: Feature sizes (mm, half a period) of the tests: inside the paper camera's sampling
#: (0.125-0.141 mm) up to about a flame's width.
FEATURES = (0.33, 0.66, 1.3, 2.6, 6.6)


@pytest.fixture(scope="module")
def camera():
    """The paper's optics on 12 x 8 lenslets: the same kernels as the paper's 180 x 90 (they
    do not depend on the lenslet count), a quicker quadrature of the weights."""
    return PlenopticCamera(n_rows=12, n_cols=8)


@pytest.fixture(scope="module")
def dense(camera):
    """The kernels of the default dense stack: 81 planes every 0.5 mm from -15 to +25 mm."""
    return exact_kernels(camera, stack_depths())


@pytest.fixture(scope="module")
def paper_map(camera, dense):
    return resolution_from_kernels(dense, FEATURES + (12.0,), (10.0, 100.0), "rows", camera)


def test_the_responses_are_the_exact_operators_spectra(camera):
    """kernel_response at the FFT canvas's frequencies is the spectrum ExactOperator applies
    (the operator held to the traced one in test_exact_operator.py), along rows and columns."""
    depths = (-12.0, 0.0, 7.5, 20.0)
    op = ExactOperator(camera, depths)
    kern = exact_kernels(camera, depths)
    lr, lc = op.canvas_shape
    for r in (1, 3, lr // 2 - 1):
        for k in range(len(depths)):
            H = kernel_response(kern, [r / lr], [k], "rows")[0][op._lit]   # the operator keeps the lit views
            assert np.allclose(H, op._spec[:, k, r, 0], rtol=0, atol=1e-12 * np.abs(H).max())
    for c in (1, 4):
        H = kernel_response(kern, np.full(len(depths), c / lc), np.arange(len(depths)), "columns")[:, op._lit]
        assert np.allclose(H, op._spec[:, :, 0, c].T, rtol=0, atol=1e-12 * np.abs(H).max())
    G = normal_matrix(kern, 3 / lr, "rows")
    S = op._spec[:, :, 3, 0]
    assert np.allclose(G, S.conj().T @ S, rtol=1e-12, atol=0)
    assert np.allclose(G, G.conj().T) and np.linalg.eigvalsh(G).min() > -1e-9 * np.abs(G).max()


def test_a_pairs_condition_is_its_normal_blocks(dense):
    """pair_conditions[s - 1, i] is cond of G's 2 x 2 block of planes i, i + s at the pair's
    frequency (mean sample / 2 x feature)."""
    s_mm = 1.3
    pc = pair_conditions(dense, s_mm, "rows")
    a = np.array([sz[0] for sz in dense.sizes_mm]) / dense.dims[1]
    for i, j in ((0, 1), (10, 19), (40, 80), (3, 60)):
        G = normal_matrix(dense, (a[i] + a[j]) / (4 * s_mm), "rows")[np.ix_([i, j], [i, j])]
        assert pc[j - i - 1, i] == pytest.approx(np.linalg.cond(G), rel=1e-6)
    assert np.isnan(pc[79, 1]) and np.isnan(pc[1, 79])       # no such pairs


def _first_below(c, t):
    """Index of the first value below t, else the last index."""
    return int(np.argmax(c < t)) if np.any(c < t) else c.size - 1


def test_the_condition_falls_as_the_planes_part(paper_map):
    """Parallax: the farther apart two planes, the less alike their views. The median
    condition falls strictly with the spacing until it first drops below 2 (past both
    thresholds); for 0.66 mm and more until it drops below 1.2, and it stays below 1.5
    after (a ripple; a 0.33 mm feature rises again to about 3.5 at 40 mm: the far plane
    blurs it out, module docstring); the closest
    pairs are the worst (> 100 for every feature of at least 0.66 mm at 0.5 mm)."""
    for fi, s in enumerate(paper_map.feature_mm[:5]):
        c = paper_map.cond_median[fi]
        first = _first_below(c, 2.0)
        assert first > 0 and np.all(np.diff(c[:first + 1]) < 0), f"{s} mm: the condition rises with spacing"
        assert np.nanargmax(c) == 0
        if s >= 0.66:
            below = _first_below(c, 1.2)
            assert below > 0 and np.all(np.diff(c[:below + 1]) < 0), f"{s} mm: the condition rises with spacing"
            assert c[below] > 1.2 or np.nanmax(c[below:]) < 1.5, f"{s} mm: the condition rises again"
            assert c[0] > 100
    assert np.all(paper_map.cond_worst >= paper_map.cond_median * (1 - 1e-12))


def test_finer_features_resolve_closer_planes(paper_map):
    sp = paper_map.spacing_interp_mm
    assert np.all(np.diff(sp[:5, 0]) > 0) and np.all(np.diff(sp[1:5, 1]) > 0)
    assert np.all(sp[:5, 1] <= sp[:5, 0])                        # a looser condition, a closer spacing
    assert np.all(np.diff(paper_map.modes[:5, 1]) <= 0) and paper_map.modes[0, 1] > paper_map.modes[4, 1]


def test_the_paper_cameras_rule_of_thumb(paper_map):
    """The probe's figures (NOTES.md, 'Depth resolution'): about 3.5 x the feature size at
    condition <= 10 and 1.1 x at <= 100; stated band 3.2-3.8 and 1.0-1.25 for 0.66-6.6 mm.
    Whole flames are not resolved within the 40 mm stack at condition 10 (12 mm: inf), and
    a 6.6 mm feature has at most 2 depth modes there, a 0.33 mm one at least 12."""
    ratio = paper_map.spacing_interp_mm[1:5] / paper_map.feature_mm[1:5, None]
    assert np.all((ratio[:, 0] > 3.2) & (ratio[:, 0] < 3.8)), ratio[:, 0]
    assert np.all((ratio[:, 1] > 1.0) & (ratio[:, 1] < 1.25)), ratio[:, 1]
    assert np.isinf(paper_map.spacing_median_mm[5, 0]) and np.isinf(paper_map.spacing_interp_mm[5, 0])
    assert paper_map.modes[4, 1] <= 2 and paper_map.modes[0, 1] >= 12
    # the grid values bracket the interpolated crossing within one stack spacing
    d = paper_map.spacing_median_mm[:5] - paper_map.spacing_interp_mm[:5]
    assert np.all((d >= -1e-9) & (d < 0.5))


def test_rows_and_columns_agree_on_a_square_camera(dense, paper_map):
    """Square pixels and a round aperture: the map does not depend on the frequency's
    direction along the lenslet rows or columns (it does on a wrong tap origin)."""
    cols = resolution_from_kernels(dense, FEATURES, (10.0, 100.0), "columns")
    assert np.allclose(cols.cond_median, paper_map.cond_median[:5], rtol=1e-9)


def test_a_feature_finer_than_the_sample_is_not_mapped(dense):
    res = resolution_from_kernels(dense, (0.05, 0.5), (10.0,))
    assert np.isnan(res.spacing_median_mm[0, 0]) and np.isnan(res.modes[0, 0])
    assert np.isfinite(res.spacing_median_mm[1, 0])
    assert "finer than a sample" in res.markdown()


def test_a_feature_finer_than_the_mean_sample_says_why_its_modes_are_not_mapped(dense):
    """A 0.128 mm feature lies between the stack's finest sample (0.125 mm, at -15 mm) and its mean (0.133 mm): its
    spacings are mapped on the near planes that sample it, while its depth modes, counted at the mean sample, are
    not. The table says what its "–" means and which planes its spacings come from (it had printed them side by side
    with no word); a table whose modes are all mapped, or whose unmapped rows are finer than every sample, says
    nothing more."""
    res = resolution_from_kernels(dense, (0.05, 0.128, 0.5), (10.0,))
    assert np.isnan(res.modes[1, 0]) and np.isfinite(res.spacing_median_mm[1, 0]) and res.modes[2, 0] > 0
    md = res.markdown()
    assert "| 0.128 | <= 0.5 (<= 0.5); <= 0.5 | – |" in md
    assert ("–: depth modes not mapped. They are counted on the whole stack at its mean sample (0.133 mm along the "
            "rows), and features of 0.128 mm are finer than that") in md
    assert "(0.128 mm: the planes at -15 to -8.5 mm)" in md and "0.05 mm" not in md.split("–: depth modes")[1]
    assert res.unmapped_modes_note() is not None
    assert resolution_from_kernels(dense, (0.05, 0.5), (10.0,)).unmapped_modes_note() is None


def test_bad_input_is_refused(camera, dense):
    for kw, match in ((dict(spacing_mm=0.0), "spacing"), (dict(spacing_mm=-1.0), "spacing"),
                      (dict(near_mm=5.0, far_mm=5.0), "near"), (dict(near_mm=10.0, far_mm=-10.0), "near"),
                      (dict(near_mm=float("nan")), "finite"), (dict(spacing_mm=0.01), "at most")):
        with pytest.raises(ValueError, match=match):
            stack_depths(**{**dict(near_mm=-15.0, far_mm=25.0, spacing_mm=0.5), **kw})
    with pytest.raises(ValueError, match="one plane"):
        depth_resolution(camera, near_mm=0.0, far_mm=1.0, spacing_mm=2.0)
    with pytest.raises(ValueError, match="axis"):
        resolution_from_kernels(dense, (1.0,), axis="up")
    with pytest.raises(ValueError, match="feature"):
        resolution_from_kernels(dense, (0.0,))
    with pytest.raises(ValueError, match="condition"):
        resolution_from_kernels(dense, (1.0,), (0.5,))
    with pytest.raises(ValueError, match="evenly spaced"):
        resolution_from_kernels(exact_kernels(camera, (0.0, 1.0, 3.0)), (1.0,))


# ---- the command ------------------------------------------------------------------------------
def test_the_command_maps_another_cameras_geometry(tmp_path, capsys):
    """9 x 9 views behind a 100 mm main lens on 40 x 30 lenslets: fewer views, less
    parallax, so a 1.3 mm feature needs a wider spacing than on the paper's camera (4.5 mm);
    by default the paper camera's stack and feature sizes are carried to it (equal parallax
    across the aperture, its lenslets), where the paper's -15 to +25 mm would hold few of the
    depths it resolves; the files are written and agree with the printed table."""
    from lf_flame.tomo.depth import depth_scale
    from lf_flame.tomo.resolution import camera_stack
    assert camera_stack(PAPER_CAMERA) == (-15.0, 25.0, 0.5, FEATURE_SIZES_MM)      # the paper's own
    other = PlenopticCamera(pixels_per_lenslet=9, n_rows=40, n_cols=30, main_focal_mm=100.0)
    near, far, spacing, features = camera_stack(other)
    from lf_flame.optics.depth_range import imaging_range_mm
    scale, (lo, hi) = depth_scale(other, 9), imaging_range_mm(other)          # within what the camera refocuses
    assert scale > 2 and near == pytest.approx(max(-15 * scale, lo), rel=0.05)
    assert far == pytest.approx(min(25 * scale, hi), rel=0.05) and lo <= near < far <= hi
    assert (far - near) / spacing == pytest.approx(80, rel=0.05) and features[1] > FEATURE_SIZES_MM[1]
    cam = tmp_path / "cam.toml"
    cam.write_text("[camera]\npixels_per_lenslet = 9\nn_rows = 40\nn_cols = 30\nmain_focal_mm = 100\n")
    out = tmp_path / "res" / "other"
    assert main(["resolution", "--camera", str(cam), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    last = near + spacing * int(np.floor((far - near) / spacing + 1e-9))      # the last plane, at or below far
    assert f"every {spacing:g} mm from {near:+g} to {last:+g} mm" in text and f"camera of {cam}" in text
    df = pd.read_csv(out.with_name("other.csv"))
    assert list(df.feature_mm) == list(features)
    assert main(["resolution", "--camera", str(cam), "--feature", *map(str, FEATURES), "--out", str(out)]) == 0
    df = pd.read_csv(out.with_name("other.csv"))
    row = df[df.feature_mm == 1.3].iloc[0]
    assert 6.0 < row.spacing_interp_mm_10 < 40.0
    assert "Provenance" in out.with_name("other.md").read_text() and out.with_name("other.png").stat().st_size > 0


def test_the_command_maps_the_paper_camera(capsys):
    assert main(["resolution"]) == 0
    text = capsys.readouterr().out
    assert "81 planes every 0.5 mm from -15 to +25 mm" in text and "the paper's camera" in text
    assert "| 1.3 | 5 (5); 4.51 | 1.5 (2); 1.44 | 4 | 5 |" in text


@pytest.mark.parametrize("args, match", [
    (["--spacing", "0"], "spacing"), (["--spacing", "-0.5"], "spacing"),
    (["--near", "10", "--far", "10"], "near"), (["--near", "20", "--far", "-5"], "near"),
    (["--camera", "no_such_camera.toml"], "not found"), (["--condition", "0.5"], "condition"),
])
def test_the_command_refuses_bad_input(args, match, capsys):
    assert main(["resolution", *args]) == 2
    assert match in capsys.readouterr().err


def test_the_command_refuses_a_file_without_a_camera(tmp_path, capsys):
    (tmp_path / "none.toml").write_text("[dataset]\nseed = 1\n")
    (tmp_path / "typo.toml").write_text("[camera]\nmain_focal = 100\n")
    assert main(["resolution", "--camera", str(tmp_path / "none.toml")]) == 2
    assert "a camera file has ['main_lens', 'microlens_array', 'sensor']" in capsys.readouterr().err
    assert main(["resolution", "--camera", str(tmp_path / "typo.toml")]) == 2
    assert "unknown camera fields" in capsys.readouterr().err


def test_the_command_maps_a_datasheet_camera(tmp_path, capsys):
    """The camera file users write (examples/own_camera.toml: a rotated grid of 10.57 px lenslet
    images) is mapped through the views decoding cuts from it (10 x 10 views of its 48 x 31
    lenslets), not refused for its grid nor replaced by the paper's camera."""
    cam = Path(__file__).resolve().parents[1] / "examples" / "own_camera.toml"
    out = tmp_path / "own"
    assert main(["resolution", "--camera", str(cam), "--near", "-10", "--far", "10.5", "--spacing", "1",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert f"camera of {cam} (its decoded views: 10 x 10 views of 48 x 31 lenslets" in text
    assert "21 planes every 1 mm from -10 to +10 mm" in text        # its last plane, not --far (it had said +10.5)
    camera = json.loads(out.with_name("own.md").read_text().split("Camera: `")[1].split("`")[0])
    assert camera["pixels_per_lenslet"] == 10 and camera["grid_rotation_deg"] == 0


def test_feature_sizes_wider_than_the_field_are_noted():
    """A camera of 3 x 3 lenslets (a field of 0.39 mm at its focal plane on the paper camera's optics) gets a note
    naming every default feature size whose period exceeds its field; the paper camera's 0.33 mm features fit its
    field along either axis and get none."""
    from lf_flame.cli.resolution import wider_than_field
    tiny = dataclasses.replace(PAPER_CAMERA, n_rows=3, n_cols=3)
    note = wider_than_field(tiny, (0.33, 6.6), "rows")
    assert note.startswith("note: features of 0.33, 6.6 mm have a period longer than the field along the rows")
    assert "3 lenslets" in note
    assert wider_than_field(PAPER_CAMERA, (0.33,), "rows") is None
    assert wider_than_field(PAPER_CAMERA, (0.33,), "diagonal") is None
