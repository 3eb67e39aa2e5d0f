"""Tiled reconstruction: in this process and on a local Dask cluster, against
`sphcover recon --tiles`, byte for byte, also when a worker dies in the middle of a run."""

import os
import sys

import cloudpickle
import pytest
from distributed import Client, LocalCluster

import sphcover


def written(tmp_path, mesh, name):
    path = tmp_path / name
    sphcover.write(path, mesh)
    return path.read_bytes()


def test_tiles_in_this_process_match_the_command_line(fixtures, run_cli, tmp_path):
    scan = fixtures / "real" / "kitten.ply"
    run_cli("recon", scan, "--tiles", "2", "-o", tmp_path / "cli.ply")
    mesh = sphcover.reconstruct(sphcover.read(scan), tiles=2)
    assert written(tmp_path, mesh, "python.ply") == (tmp_path / "cli.ply").read_bytes()
    assert mesh.stats["watertight"] and mesh.stats["components"] == 1


def test_a_streamed_file_matches_the_command_line(fixtures, run_cli, tmp_path):
    scan = fixtures / "real" / "kitten.ply"
    run_cli("recon", scan, "--tiles", "2", "--stream", "-o", tmp_path / "cli.ply")
    mesh = sphcover.reconstruct_file(scan, tiles=2, scratch=tmp_path)
    assert written(tmp_path, mesh, "python.ply") == (tmp_path / "cli.ply").read_bytes()
    assert mesh.stats["watertight"] and mesh.stats["components"] == 1
    assert mesh.stats["tiles"] == 8 and mesh.point_confidence is None
    # The tile files went with the run.
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".sphcover-tiles")]


def test_a_streamed_lidar_file_without_normals_matches_the_command_line(
    fixtures, run_cli, tmp_path
):
    scan = fixtures / "real" / "urban.laz"
    run_cli("recon", scan, "--tiles", "2", "--stream", "-o", tmp_path / "cli.ply")
    mesh = sphcover.reconstruct_file(scan, tiles=2, scratch=tmp_path)
    assert written(tmp_path, mesh, "python.ply") == (tmp_path / "cli.ply").read_bytes()
    assert mesh.stats["normals_estimated"]


def killing_first_attempt(tile, options, marker):
    """The tile's function, except that the first attempt at the first tile ends its worker
    process at once, as a machine that goes down would."""
    if not os.path.exists(marker):
        with open(marker, "w"):
            pass
        os._exit(1)
    return sphcover.tile_function(tile, options)


def test_a_worker_killed_mid_run_changes_nothing(fixtures, run_cli, tmp_path):
    scan = fixtures / "real" / "kitten.ply"
    run_cli("recon", scan, "--tiles", "2", "-o", tmp_path / "cli.ply")
    marker = str(tmp_path / "killed")
    # The workers are other processes: they get this module's functions by value.
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, Client(cluster) as client:

        def map_tiles(inputs, options):
            futures = client.map(
                killing_first_attempt,
                inputs,
                options=options,
                marker=marker,
                pure=False,
            )
            return client.gather(futures)

        mesh = sphcover.reconstruct(sphcover.read(scan), tiles=2, map_tiles=map_tiles)
        assert os.path.exists(marker), "no worker was killed"
        assert written(tmp_path, mesh, "killed.ply") == (tmp_path / "cli.ply").read_bytes()
        # The ordinary path through the cluster gives the same bytes, with the inputs as
        # bytes or as files in a scratch directory (removed afterwards).
        mesh = sphcover.reconstruct(sphcover.read(scan), tiles=(2, 2, 2), client=client)
        assert written(tmp_path, mesh, "dask.ply") == (tmp_path / "cli.ply").read_bytes()
        scratch = tmp_path / "scratch"
        scratch.mkdir()
        mesh = sphcover.reconstruct(
            sphcover.read(scan), tiles=2, client=client, scratch=scratch
        )
        assert written(tmp_path, mesh, "files.ply") == (tmp_path / "cli.ply").read_bytes()
        assert list(scratch.iterdir()) == []


def test_bad_tilings_and_damaged_tiles_are_refused(fixtures):
    cloud = sphcover.read(fixtures / "real" / "kitten.ply")
    for options in [
        dict(tiles=(0, 1, 1)),
        dict(tiles=2, halo=2.0),
        dict(tiles=2, method="graphcut"),
    ]:
        with pytest.raises(sphcover.BadInputError):
            sphcover.reconstruct(cloud, **options)
    with pytest.raises(sphcover.BadInputError, match="tile input"):
        sphcover.tile_function(b"not a tile", {})
    with pytest.raises(sphcover.SphcoverError, match="map_tiles"):
        sphcover.reconstruct(cloud, tiles=2, map_tiles=lambda inputs, options: [None])


def test_options_reach_the_tasks_as_they_reach_the_tiles_here(fixtures, tmp_path):
    """The tasks rebuild the options from what `reconstruct` hands them: with options other
    than the defaults, a plain Python map gives the in-process surface byte for byte."""
    cloud = sphcover.read(fixtures / "real" / "kitten.ply")
    options = dict(tiles=(2, 1, 2), eps=8e-3, k=20.0, position_fit=4.0, normal_fit=32.0, seed=3)
    here = sphcover.reconstruct(cloud, **options)
    mapped = sphcover.reconstruct(
        cloud,
        map_tiles=lambda inputs, opts: [sphcover.tile_function(t, opts) for t in inputs],
        **options,
    )
    assert written(tmp_path, here, "here.ply") == written(tmp_path, mapped, "mapped.ply")
    plain = sphcover.reconstruct(cloud, tiles=(2, 1, 2))
    assert written(tmp_path, plain, "plain.ply") != written(tmp_path, here, "here.ply")


def killing_first_streamed_attempt(task, options, marker):
    """A streamed tile's task, except that the first attempt at the first task ends its
    worker process at once."""
    if not os.path.exists(marker):
        with open(marker, "w"):
            pass
        os._exit(1)
    return sphcover.streamed_tile_function(task, options)


def test_a_streamed_file_on_a_cluster_with_a_killed_worker_matches_the_command_line(
    fixtures, run_cli, tmp_path
):
    scan = fixtures / "real" / "kitten.ply"
    run_cli("recon", scan, "--tiles", "2", "--stream", "-o", tmp_path / "cli.ply")
    marker = str(tmp_path / "killed")
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, Client(cluster) as client:

        def map_tiles(tasks, options):
            futures = client.map(
                killing_first_streamed_attempt,
                tasks,
                options=options,
                marker=marker,
                pure=False,
            )
            return client.gather(futures)

        mesh = sphcover.reconstruct_file(scan, tiles=2, scratch=scratch, map_tiles=map_tiles)
        assert os.path.exists(marker), "no worker was killed"
        assert written(tmp_path, mesh, "killed.ply") == (tmp_path / "cli.ply").read_bytes()
        # The plain Dask runner gives the same surface.
        mesh = sphcover.reconstruct_file(scan, tiles=2, scratch=scratch, client=client)
        assert written(tmp_path, mesh, "dask.ply") == (tmp_path / "cli.ply").read_bytes()
    assert not list(scratch.iterdir())
