"""Map files (map_server PGM + YAML): round trip, orientation, bad input; the PNG picture."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import yaml

from smokyslam.errors import MapFileError
from smokyslam.geometry import GridSpec
from smokyslam.mapio import load_map, save_map, with_implicit_walls
from smokyslam.mapping.render import map_picture, render_map_png
from smokyslam.sim.world import box_world
from smokyslam.types import GroundTruthMap


def _l_shaped_walls() -> tuple[np.ndarray, GridSpec]:
    """A 3 m x 2 m map at (-1, 0.5): a wall along its south edge, a post near the north-east."""
    spec = GridSpec((-1.0, 0.5), 0.1, (20, 30))
    cells = np.zeros(spec.shape, dtype=np.int8)
    cells[0, :] = 100  # y in [0.5, 0.6): the south wall
    cells[17, 25] = 100  # the post at (1.55, 2.25)
    cells[10:, :5] = -1  # unknown north-west corner
    return cells, spec


def test_round_trip_keeps_cells_origin_and_resolution(tmp_path):
    cells, spec = _l_shaped_walls()
    path = save_map(tmp_path / "maps" / "radar_sparse.yaml", cells, spec)
    assert path.with_suffix(".pgm").is_file() and path.with_suffix(".png").is_file()
    description = yaml.safe_load(path.read_text())
    assert description["origin"] == [-1.0, 0.5, 0.0] and description["mode"] == "trinary"
    assert description["image"] == "radar_sparse.pgm" and description["resolution"] == 0.1
    loaded = load_map(path)
    np.testing.assert_array_equal(loaded.cells, cells)
    assert loaded.spec == spec
    # Walls read back where they were drawn, in world coordinates.
    post = loaded.spec.cells_of(np.array([[1.55, 2.25]]))[0]
    assert loaded.cells[post[1], post[0]] == 100
    south = loaded.spec.cells_of(np.array([[0.0, 0.55]]))[0]
    assert south.tolist() == [10, 0] and loaded.cells[0, 10] == 100


def test_image_rows_run_north_to_south(tmp_path):
    """A hand-written PGM: row 0 of the image is the top (north) edge of the map."""
    pixels = np.full((4, 5), 254, dtype=np.uint8)
    pixels[0, :] = 0  # black top row: the north wall
    pixels[3, 4] = 205  # grey bottom-right pixel: unknown at the south-east corner
    header = b"P5\n5 4\n255\n"
    (tmp_path / "hand.pgm").write_bytes(header + pixels.tobytes())
    (tmp_path / "hand.yaml").write_text(
        "image: hand.pgm\nresolution: 0.5\norigin: [2.0, -1.0, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n"
    )
    loaded = load_map(tmp_path / "hand.yaml")
    assert loaded.spec.shape == (4, 5)
    north = loaded.spec.cells_of(np.array([[3.0, 0.9]]))[0]  # y in [0.5, 1.0): top row
    assert loaded.cells[north[1], north[0]] == 100
    assert np.all(loaded.cells[3, :] == 100) and np.all(loaded.cells[:3, :4] == 0)
    south_east = loaded.spec.cells_of(np.array([[4.3, -0.8]]))[0]
    assert south_east.tolist() == [4, 0] and loaded.cells[0, 4] == -1


def test_bad_map_files_give_clear_errors(tmp_path):
    cells, spec = _l_shaped_walls()
    good = save_map(tmp_path / "good.yaml", cells, spec)
    description = yaml.safe_load(good.read_text())

    missing = dict(description, image="nowhere.pgm")
    (tmp_path / "missing.yaml").write_text(yaml.safe_dump(missing))
    with pytest.raises(MapFileError, match="map image not found"):
        load_map(tmp_path / "missing.yaml")

    (tmp_path / "text.pgm").write_text("this is not an image\n")
    (tmp_path / "text.yaml").write_text(yaml.safe_dump(dict(description, image="text.pgm")))
    with pytest.raises(MapFileError, match="not a readable PGM/PNG image"):
        load_map(tmp_path / "text.yaml")

    (tmp_path / "negative.yaml").write_text(yaml.safe_dump(dict(description, resolution=-0.1)))
    with pytest.raises(MapFileError, match="resolution must be a positive number"):
        load_map(tmp_path / "negative.yaml")

    with pytest.raises(MapFileError, match="map file not found"):
        load_map(tmp_path / "absent.yaml")

    (tmp_path / "vague.yaml").write_text(yaml.safe_dump(dict(description, unknown="maybe")))
    with pytest.raises(MapFileError, match="unknown must be one of unobserved, solid"):
        load_map(tmp_path / "vague.yaml")

    (tmp_path / "binary.yaml").write_bytes(b"\x89MCAP0\r\n\x00\xff")  # a log given as the map
    with pytest.raises(MapFileError, match="not a text \\(UTF-8\\) map description"):
        load_map(tmp_path / "binary.yaml")

    (tmp_path / "words.yaml").write_text(yaml.safe_dump(dict(description, occupied_thresh="high")))
    with pytest.raises(MapFileError, match="occupied_thresh must be a number, got 'high'"):
        load_map(tmp_path / "words.yaml")

    (tmp_path / "listed.yaml").write_text(yaml.safe_dump(dict(description, image=["a.pgm"])))
    with pytest.raises(MapFileError, match="image must be a file name"):
        load_map(tmp_path / "listed.yaml")


def test_what_unknown_means_is_kept_or_read_from_what_the_map_draws(tmp_path):
    cells, spec = _l_shaped_walls()
    plain = save_map(tmp_path / "plain.yaml", cells, spec)  # map_server's keys only
    assert "unknown" not in yaml.safe_load(plain.read_text())
    assert load_map(plain).unknown == "unobserved"  # it draws its walls
    solid = save_map(tmp_path / "solid.yaml", cells, spec, unknown="solid")
    assert load_map(solid).unknown == "solid"
    bare = np.where(cells == 100, -1, cells).astype(np.int8)  # the same map, no wall drawn
    bare[5, 5] = 100  # but a speck
    assert load_map(save_map(tmp_path / "bare.yaml", bare, spec)).unknown == "solid"
    ours = save_map(tmp_path / "ours.yaml", bare, spec, unknown="unobserved")
    assert load_map(ours).unknown == "unobserved"


def test_implicit_walls_are_the_unknown_cells_that_touch_free_space():
    cells = np.full((7, 9), -1, dtype=np.int8)
    cells[2:5, 2:7] = 0  # a 5 x 3 free room
    cells[1, 3:6] = 100  # of its walls only part of one is drawn
    walled = with_implicit_walls(cells)
    ring = ~np.pad(np.ones((3, 5), bool), 1)  # every cell touching the room, corners included
    assert np.array_equal(walled[1:6, 1:8] == 100, ring)
    assert (walled[[0, 6], :] == -1).all() and (walled[:, [0, 8]] == -1).all()  # deeper: unknown
    assert (walled[2:5, 2:7] == 0).all()  # the room itself is unchanged
    assert cells[1, 1] == -1  # the input is left alone


def test_picture_overlays_truth_walls_in_red(tmp_path):
    world = box_world()
    truth = GroundTruthMap(0.0, world.ground_truth_cells(), world.spec)
    cells = np.full(world.spec.shape, -1, dtype=np.int8)
    cells[1:-1, 1:-1] = 0
    cells[10, 10] = 100  # a false obstacle at (0.95, 0.95)
    image, canvas = map_picture(cells, world.spec, truth)
    assert canvas == world.spec and image.shape == (*world.spec.shape, 3)

    def pixel(x_m, y_m):
        ix, iy = canvas.cells_of(np.array([[x_m, y_m]]))[0]
        return image[iy, ix].tolist()

    assert pixel(-0.05, 3.0) == [217, 102, 102]  # a wall the map leaves unknown: grey + red
    assert pixel(0.95, 0.95) == [0, 0, 0]  # the map's own obstacle, no wall there
    assert pixel(3.0, 4.5) == [254, 254, 254]  # free
    # The picture itself: a fixed width, axes, title and legend (matplotlib draws them).
    path = render_map_png(
        tmp_path / "map.png", cells, world.spec, truth, np.array([[1.0, 1.0], [7.0, 5.0]]), "t"
    )
    png = cv2.imread(str(path))
    assert png.shape[1] == 770 and 300 <= png.shape[0] <= 1100
    blue = np.abs(png.astype(int) - [200, 80, 0]).max(axis=2) <= 40  # the path, BGR
    assert blue.sum() > 100
