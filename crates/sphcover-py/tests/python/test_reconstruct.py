"""`reconstruct` against `sphcover recon`: the same mesh, byte for byte, the same errors."""

import numpy as np
import pytest

import sphcover
from conftest import fibonacci_sphere


def python_recon_bytes(tmp_path, scan, **options):
    cloud = sphcover.read(scan)
    mesh = sphcover.reconstruct(cloud, **options)
    path = tmp_path / "python.ply"
    sphcover.write(path, mesh)
    return mesh, path.read_bytes()


def test_kitten_matches_the_command_line_byte_for_byte(fixtures, run_cli, tmp_path):
    scan = fixtures / "real" / "kitten.ply"
    run_cli("recon", scan, "-o", tmp_path / "cli.ply")
    mesh, written = python_recon_bytes(tmp_path, scan)
    assert written == (tmp_path / "cli.ply").read_bytes()
    assert mesh.stats["watertight"] and mesh.stats["points"] == 5210
    assert len(mesh.point_confidence) == 5210 and mesh.outliers.dtype == np.bool_
    assert mesh.confidence is mesh.values and len(mesh.values) == len(mesh.vertices)


def test_colours_reach_the_vertices_as_the_command_line_carries_them(run_cli, tmp_path):
    # The upper half of a sphere red, the lower blue: every vertex takes its side's colour.
    points, normals = fibonacci_sphere(3000)
    colors = np.where(points[:, 2:3] > 0, [[220, 30, 30]], [[30, 30, 220]]).astype(np.uint8)
    scan = tmp_path / "coloured.ply"
    sphcover.write(scan, sphcover.PointCloud(points=points, normals=normals, colors=colors))
    run_cli("recon", scan, "-o", tmp_path / "cli.ply")
    mesh, written = python_recon_bytes(tmp_path, scan)
    assert written == (tmp_path / "cli.ply").read_bytes()
    assert mesh.colors.shape == (len(mesh.vertices), 3)
    away = np.abs(mesh.vertices[:, 2]) > 0.02
    upper = mesh.vertices[away, 2] > 0
    np.testing.assert_array_equal(mesh.colors[away][upper], [[220, 30, 30]] * upper.sum())
    np.testing.assert_array_equal(mesh.colors[away][~upper], [[30, 30, 220]] * (~upper).sum())
    plain = sphcover.reconstruct(points, normals)
    assert plain.colors is None
    np.testing.assert_array_equal(plain.vertices, mesh.vertices)


def test_max_memory_decides_as_the_command_line_does(fixtures, run_cli, tmp_path):
    scan = fixtures / "real" / "kitten.ply"
    # Between the predicted peaks of depth 5 and of the default depth 6 for 5,210 points.
    budget = 123_000_000
    run_cli("recon", scan, "-o", tmp_path / "cli.ply", "--max-memory", str(budget))
    with pytest.warns(UserWarning, match="max_memory .*using depth 5"):
        mesh, written = python_recon_bytes(tmp_path, scan, max_memory=budget)
    assert written == (tmp_path / "cli.ply").read_bytes()
    assert mesh.stats["depth"] == 5
    assert mesh.stats["memory"]["depth_lowered_from"] == 6
    assert mesh.stats["memory"]["budget_bytes"] == budget

    cli = run_cli("recon", scan, "-o", tmp_path / "no.ply", "--max-memory", "1M", expect_ok=False)
    assert cli.returncode == 2
    with pytest.raises(sphcover.BadInputError) as raised:
        sphcover.reconstruct(sphcover.read(scan), max_memory="1M")
    assert str(raised.value).replace("max_memory", "--max-memory") in cli.stderr
    with pytest.raises(sphcover.BadInputError, match="; depth 5 would fit .* lower depth$"):
        sphcover.reconstruct(sphcover.read(scan), max_memory=budget, depth=7)
    assert "memory" not in sphcover.reconstruct(sphcover.read(scan), depth=5).stats


def test_a_given_eps_is_obeyed_and_overrides_are_reported(fixtures, run_cli, tmp_path):
    scan = fixtures / "sphere_noisy_2k.ply"
    cloud = sphcover.read(scan)
    auto = sphcover.reconstruct(cloud)
    assert auto.stats["eps"] > auto.stats["eps_requested"] == 2.5e-3
    assert auto.stats["tolerance_note"].startswith("cover tolerance raised from 2.500e-3")
    run_cli("recon", scan, "-o", tmp_path / "cli.ply", "--eps", "0.004")
    with pytest.warns(UserWarning, match="eps 4.000e-3 is below"):
        mesh, written = python_recon_bytes(tmp_path, scan, eps=0.004)
    assert written == (tmp_path / "cli.ply").read_bytes()
    assert mesh.stats["eps"] == 0.004
    assert sphcover.reconstruct(cloud, eps=0.004, noise="auto").stats["eps"] == auto.stats["eps"]
    assert sphcover.reconstruct(cloud, noise=0.002).stats["eps"] == 0.008
    with pytest.raises(sphcover.BadInputError, match="noise"):
        sphcover.reconstruct(cloud, noise="loud")


# The ε given lies below the noise floor: the warning is the subject of the test above.
@pytest.mark.filterwarnings("ignore:eps 4.000e-3 is below")
def test_options_match_the_command_line_flags(fixtures, run_cli, tmp_path):
    scan = fixtures / "sphere_noisy_2k.ply"
    run_cli(
        "recon", scan, "-o", tmp_path / "cli.ply", "--method", "diffusion", "--eps", "0.004",
        "--trim", "--depth", "7", "--no-refine", "--estimate-normals",
        "--normal-neighbours", "15", "--position-fit", "2", "--seed", "3",
    )
    _, written = python_recon_bytes(
        tmp_path, scan, method="diffusion", eps=0.004, trim=True, depth=7, refine=False,
        estimate_normals=True, normal_neighbours=15, position_fit=2.0, seed=3,
    )
    assert written == (tmp_path / "cli.ply").read_bytes()


def test_the_result_does_not_depend_on_the_thread_count(fixtures):
    cloud = sphcover.read(fixtures / "sphere_2k.ply")
    one = sphcover.reconstruct(cloud, threads=1)
    two = sphcover.reconstruct(cloud, threads=2)
    np.testing.assert_array_equal(one.vertices, two.vertices)
    np.testing.assert_array_equal(one.faces, two.faces)


@pytest.mark.parametrize(
    "option, flag, value",
    [
        ("eps", "--eps", 2.0),
        ("k", "--k", -1.0),
        ("depth", "--depth", 20),
        ("normal_neighbours", "--normal-neighbours", 2),
        ("normal_fit", "--normal-fit", -0.5),
    ],
)
def test_options_out_of_range_raise_the_command_line_message(
    fixtures, run_cli, tmp_path, option, flag, value
):
    scan = fixtures / "sphere_2k.ply"
    with pytest.raises(sphcover.BadInputError) as raised:
        sphcover.reconstruct(sphcover.read(scan), **{option: value})
    result = run_cli("recon", scan, "-o", tmp_path / "x.ply", f"{flag}={value}", expect_ok=False)
    assert result.returncode == 2
    # Same message, the option spelled as a keyword instead of a flag.
    assert f"{flag} {str(raised.value).split(' ', 1)[1]}" in result.stderr


def test_unusable_input_raises_the_command_line_message(run_cli, tmp_path):
    points = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    normals = np.tile([0.0, 0.0, 1.0], (3, 1))
    sphcover.write(tmp_path / "three.ply", sphcover.PointCloud(points=points, normals=normals))
    with pytest.raises(sphcover.BadInputError) as raised:
        sphcover.reconstruct(points, normals)
    result = run_cli("recon", tmp_path / "three.ply", "-o", tmp_path / "x.ply", expect_ok=False)
    assert result.returncode == 2
    assert f"three.ply: {raised.value}" in result.stderr


def test_progress_reports_every_stage_in_order(fixtures):
    seen = []
    sphcover.reconstruct(
        sphcover.read(fixtures / "sphere_2k.ply"),
        progress=lambda name, index, count: seen.append((name, index, count)),
    )
    assert [s[1] for s in seen] == list(range(len(seen)))
    assert {s[2] for s in seen} == {len(seen)}
    assert seen[0][0] == "normalise" and "polygonise" in [s[0] for s in seen]


def test_an_exception_in_the_progress_callback_ends_the_call(fixtures):
    def fail(name, index, count):
        raise RuntimeError(f"stop at {name}")

    with pytest.raises(RuntimeError, match="stop at normalise"):
        sphcover.reconstruct(sphcover.read(fixtures / "sphere_2k.ply"), progress=fail)


def test_progress_true_shows_the_stages_on_stderr(fixtures, capsys):
    sphcover.reconstruct(sphcover.read(fixtures / "sphere_2k.ply"), progress=True)
    # A tqdm bar when tqdm is installed, else one line per stage: both name the stages.
    assert "normalise" in capsys.readouterr().err


def test_an_open_scan_leaves_out_what_was_never_seen_as_the_command_line_does(
    fixtures, run_cli, tmp_path
):
    scan = fixtures / "real" / "hippo2.ply"
    run_cli("recon", scan, "-o", tmp_path / "cli.ply")
    run_cli("recon", scan, "-o", tmp_path / "cli_closed.ply", "--trim", "off")
    mesh, written = python_recon_bytes(tmp_path, scan)
    assert written == (tmp_path / "cli.ply").read_bytes()
    assert mesh.stats["unseen_area_fraction"] > 0.5 and not mesh.stats["watertight"]
    assert mesh.stats["one_view"]
    closed, written = python_recon_bytes(tmp_path, scan, trim=False)
    assert written == (tmp_path / "cli_closed.ply").read_bytes()
    assert closed.stats["unseen_area_fraction"] == 0.0
    assert closed.stats["one_view"]
