"""Robot inputs that cannot hurt the user (issue 61, items 2, 5, 6, 7 and 11 in part):
``roomseg-segment`` never replaces a folder that is or holds an input, nor one it did not
write; a FIFO or ``/dev/zero`` given as an input is one line, never a hang or a read without
end; labels, messages and bag maps are bounded; a non-finite transform is one line naming the
message and stamp; ``bag_options.max_clock_jump_s=-1`` is refused; a full disk names the file
of the output bag."""

from __future__ import annotations

import errno
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("rosbags")

from bag_run import CLASSES_ARG, house, write_files  # noqa: E402

from benchmark.commands import segment  # noqa: E402
from envs.bags.read import MAX_LABEL_BYTES, BagOptions, check_label, read_bag  # noqa: E402
from envs.bags.source import MAX_MESSAGE_BYTES, BagError, regular_file  # noqa: E402
from envs.bags.synthetic import write_robot_bag  # noqa: E402
from envs.bags.transforms import TfBuffer  # noqa: E402
from envs.bags.write import write_segmentation_bag  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
ENV = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{ROOT / 'tests'}"}
FAST = ["bag_options.progress=false", "figure=false", "bag_options.out_format=none"]
ALL_VIEWS = BagOptions(min_distance_m=0, min_turn_deg=0)


@pytest.fixture(scope="module")
def h():
    return house()


@pytest.fixture(scope="module")
def bag(h, tmp_path_factory):
    """A good ROS 1 bag of string labels (the example building's autotrace run)."""
    return write_robot_bag(tmp_path_factory.mktemp("bag") / "run.bag", "ros1", h.run(label_type="string"))


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip().splitlines()
    err = [ln for ln in err if ln.startswith("error: ")]
    assert len(err) == 1, err
    return err[0]


def _tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# ---------------------------------------------------------------- item 2: an input is never deleted


def test_overwrite_never_replaces_the_folder_holding_the_bag(bag, tmp_path, capsys):
    """bag=D/run.bag out=D overwrite=true deleted the bag and notes.txt with exit 0."""
    d = tmp_path / "D"
    d.mkdir()
    (d / "run.bag").write_bytes(bag.read_bytes())
    (d / "notes.txt").write_text("my notes\n")
    before = _tree(d)
    assert segment.main([f"bag={d / 'run.bag'}", f"out={d}", "overwrite=true", *FAST]) == 2
    line = _one_line(capsys)
    assert f"out={d} holds the input bag={d / 'run.bag'}" in line, line
    assert _tree(d) == before


def test_overwrite_never_replaces_a_ros2_bag_folder_given_as_out(h, tmp_path, capsys):
    d = write_robot_bag(tmp_path / "run2", "mcap", h.run(label_type="string"))
    before = _tree(d)
    assert before and any(name.endswith(".mcap") for name in before)
    assert segment.main([f"bag={d}", f"out={d}", "overwrite=true", *FAST]) == 2
    assert f"out={d} is the input bag={d}" in _one_line(capsys)
    assert _tree(d) == before


@pytest.mark.parametrize("key", ["map", "poses", "labels"])
def test_overwrite_never_replaces_a_folder_holding_a_file_input(h, tmp_path, capsys, key):
    """Even a folder that carries the marker (a user who later put an input into an output
    folder) is not replaced while it holds an input."""
    args = dict(a.split("=", 1) for a in write_files(h, tmp_path / "files") if not a.startswith("classes="))
    d = tmp_path / "D"
    d.mkdir()
    (d / segment.MARKER).write_text("roomseg-segment output folder\n")
    args[key] = str(Path(args[key]).rename(d / Path(args[key]).name))  # only this input is in D
    out = d
    before = _tree(d)
    assert segment.main([f"{k}={v}" for k, v in args.items()] + [CLASSES_ARG, f"out={out}", "overwrite=true",
                                                                  "figure=false"]) == 2
    assert f"out={out} holds the input {key}={args[key]}" in _one_line(capsys)
    assert _tree(d) == before


def test_overwrite_replaces_only_a_folder_the_command_wrote(bag, tmp_path, capsys):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("not an output\n")
    assert segment.main([f"bag={bag}", f"out={mine}", "overwrite=true", *FAST]) == 2
    line = _one_line(capsys)
    assert "was not written by roomseg-segment" in line and segment.MARKER in line, line
    assert _tree(mine) == {"notes.txt": b"not an output\n"}
    out = tmp_path / "out"
    assert segment.main([f"bag={bag}", f"out={out}", *FAST]) == 0
    assert (out / segment.MARKER).is_file()
    (out / "old.txt").write_text("from the first run\n")
    assert segment.main([f"bag={bag}", f"out={out}", "overwrite=true", *FAST]) == 0
    assert (out / segment.MARKER).is_file() and not (out / "old.txt").exists()


# ---------------------------------------------------------------- item 5: non-files are refused, never read


def _cli(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    """roomseg-segment in a child process: a reader that blocks on a FIFO or reads /dev/zero
    without end fails the test by its timeout instead of hanging it."""
    return subprocess.run([sys.executable, "-m", "benchmark.commands.segment", *args], cwd=ROOT, env=ENV,
                          capture_output=True, text=True, timeout=timeout)


@pytest.mark.slow
@pytest.mark.parametrize("case", ["fifo bag", "dev-zero bag", "dev-zero metadata.yaml", "fifo map", "dev-zero labels"])
def test_a_fifo_or_a_device_is_one_line_not_a_hang(h, tmp_path, case):
    what, key = case.split(" ")
    target = tmp_path / "in"
    if key == "metadata.yaml":
        bag = write_robot_bag(tmp_path / "run2", "mcap", h.run(label_type="string"))
        (bag / "metadata.yaml").unlink()
        target, args = bag / "metadata.yaml", [f"bag={bag}"]
        key = "bag"
    elif key == "bag":
        target = tmp_path / "run.bag"
        args = [f"bag={target}"]
    else:
        args = write_files(h, tmp_path / "files")
        name = "map.yaml" if key == "map" else "labels.csv"
        target = tmp_path / "files" / name
        target.unlink()
    if what == "fifo":
        os.mkfifo(target)
    else:
        target.symlink_to("/dev/zero")
    r = _cli(*args, f"out={tmp_path / 'out'}", "segmenter=voronoi" if key == "map" else "figure=false",
             "bag_options.progress=false")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    kind = "a FIFO (named pipe)" if what == "fifo" else "(a symbolic link to /dev/zero) is a character device"
    assert f"{key}={target}" in lines[0] and kind in lines[0] and "expected a regular file" in lines[0], lines
    assert not (tmp_path / "out").exists()


def test_regular_file_checks_without_opening(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)  # opening it would block: regular_file only stats it
    with pytest.raises(ValueError, match=r"labels=.*pipe is a FIFO \(named pipe\); expected a regular file"):
        regular_file(fifo, "labels")
    with pytest.raises(ValueError, match="is a folder"):
        regular_file(tmp_path, "poses")
    with pytest.raises(FileNotFoundError, match="does not exist"):
        regular_file(tmp_path / "none.csv", "poses")
    (tmp_path / "ok.csv").write_text("x\n")
    (tmp_path / "link.csv").symlink_to(tmp_path / "ok.csv")
    assert regular_file(tmp_path / "link.csv", "poses") == tmp_path / "link.csv"


# ---------------------------------------------------------------- item 6: labels, messages, maps bounded


@pytest.mark.parametrize("label,why", [
    ("x" * 50_000, f"is 50000 bytes, over the limit of {MAX_LABEL_BYTES} bytes a class name"),
    ("<script>", "holds '<' (U+003C)"),
    ("kit\x00chen", "holds '\\x00' (U+0000)"),
    ("kitchen\u202e", "holds '\\u202e' (U+202E)"),
])
def test_a_label_that_is_no_class_name_is_one_line_at_its_message(h, tmp_path, label, why):
    labels = list(h.labels)
    labels[3] = label
    p = write_robot_bag(tmp_path / "run.bag", "ros1", h.run(label_type="string", labels=labels))
    with pytest.raises(BagError) as e:
        read_bag(p, ALL_VIEWS)
    text = str(e.value)
    assert text.startswith(f"{p} /room_label at 1700000000.300000000 s: class name ") and why in text, text
    assert len(text) < 300 and "\n" not in text  # the name is cut short and escaped


def test_a_long_label_stops_the_command_in_one_line(h, tmp_path, capsys):
    labels = list(h.labels)
    labels[0] = "kitchen" * 100_000  # 700 kB
    p = write_robot_bag(tmp_path / "run.bag", "ros1", h.run(label_type="string", labels=labels))
    assert segment.main([f"bag={p}", f"out={tmp_path / 'out'}", *FAST]) == 2
    line = _one_line(capsys)
    assert "/room_label at 1700000000.000000000 s: class name 'kitchenkitchen" in line and "700000 bytes" in line
    assert len(line) < 400 and not (tmp_path / "out").exists()


def test_check_label_passes_the_configured_classes_and_real_names():
    assert check_label("living_room", None, "w") == "living_room"
    assert check_label("Küche", None, "w") == "Küche"
    assert check_label({"Living Room": 0.7, "kitchen": 0.3}, ("living room", "kitchen"), "w")
    assert check_label("<odd>", ("<odd>",), "w") == "<odd>"  # a class the user configured is taken as it is
    with pytest.raises(BagError, match="^w: class name"):
        check_label({"kitchen": 0.5, "a\tb": 0.5}, None, "w")


def test_a_message_over_the_limit_is_not_decoded(bag):
    assert MAX_MESSAGE_BYTES == 128 * 1024 * 1024
    with pytest.raises(BagError, match=r"topic /map at 1700000000\.000000000 s: a nav_msgs/msg/OccupancyGrid message "
                                       r"of 46\d\d\d bytes, over the limit of 10000 bytes a message"):
        read_bag(bag, BagOptions(max_message_bytes=10_000))


def test_a_bag_map_over_the_map_size_limit_is_one_line(bag, tmp_path, capsys):
    assert BagOptions().max_map_pixels == 20_000_000
    with pytest.raises(BagError, match=r"OccupancyGrid of 260 x 180 = 46800 cells, over the map-size limit of 40000"):
        read_bag(bag, BagOptions(max_map_pixels=40_000))
    assert segment.main([f"bag={bag}", "max_map_pixels=40000", f"out={tmp_path / 'out'}", *FAST]) == 2
    line = _one_line(capsys)
    assert f"{bag} /map at 1700000000.000000000 s: OccupancyGrid of 260 x 180 = 46800 cells" in line, line


# ---------------------------------------------------------------- item 7: non-finite transforms


@pytest.mark.parametrize("bad", [math.nan, math.inf])
@pytest.mark.parametrize("pose_topic", [None, "pose"])
def test_a_non_finite_transform_is_one_line_naming_message_and_stamp(h, tmp_path, bad, pose_topic):
    """A NaN pose dropped 3 of 219 views with exit 0 and a numpy warning."""
    run = h.run(label_type="string", pose_topic=pose_topic)
    run.route = h.route.copy()
    run.route[5, 0] = bad
    p = write_robot_bag(tmp_path / "run.bag", "ros1", run)
    with pytest.raises(BagError) as e:
        read_bag(p, ALL_VIEWS)
    topic, edge = ("/tf", "odom -> base_link") if pose_topic is None else ("/camera_pose", "map -> camera_pose")
    assert str(e.value).startswith(f"{p} {topic} at 1700000000.500000000 s: transform {edge} has translation ["), e.value
    assert "expected finite numbers and a unit quaternion" in str(e.value)


def test_a_zero_quaternion_is_refused():
    tf = TfBuffer()
    with pytest.raises(BagError, match=r"^/tf at 0\.000000005 s: transform map -> odom .* rotation \(x, y, z, w\) "
                                       r"\[0\.0, 0\.0, 0\.0, 0\.0\]"):
        tf.add("map", "odom", 5, (0, 0, 0), (0, 0, 0, 0), False, "/tf")
    tf.add("map", "odom", 5, (1e300, 0, 0), (0, 0, 0, 2.0), False, "/tf")  # finite: taken (normalised)
    assert np.isfinite(tf.edge_at("odom", 5)).all()


# ---------------------------------------------------------------- item 11: options in range, a full disk


@pytest.mark.parametrize("key,value", [("max_clock_jump_s", -1), ("tf_tolerance_s", math.nan),
                                       ("tf_max_gap_s", -0.5), ("min_distance_m", math.inf)])
def test_bag_options_out_of_range_are_one_line(key, value):
    with pytest.raises(ValueError, match=rf"^bag_options\.{key}={value!r}; expected a finite number >= 0$"):
        BagOptions(**{key: value})


def test_a_negative_clock_jump_is_refused_by_the_command(bag, tmp_path, capsys):
    """max_clock_jump_s=-1 was taken and reported a clock jump that is not there."""
    assert segment.main([f"bag={bag}", "bag_options.max_clock_jump_s=-1", f"out={tmp_path / 'out'}", *FAST]) == 2
    assert _one_line(capsys) == "error: ValueError: bag_options.max_clock_jump_s=-1.0; expected a finite number >= 0"


@pytest.fixture
def full_disk(tmp_path):
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mnt)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({r.stderr.strip() or 'not root'})")
    try:
        with open(mnt / "filler", "wb", buffering=0) as f:
            try:
                while True:
                    f.write(b"\0" * 4096)
            except OSError as e:
                assert e.errno == errno.ENOSPC
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)


@pytest.mark.parametrize("fmt,name", [("ros1", "segmentation.bag"), ("mcap", "segmentation.mcap")])
def test_a_full_disk_names_the_output_bag(full_disk, fmt, name):
    occ = np.zeros((200, 300), np.int8)
    rooms = {"type": "FeatureCollection", "features": []}
    with pytest.raises(OSError) as e:
        write_segmentation_bag(full_disk / name, fmt, "map", 10**18, 0.05, (0.0, 0.0, 0.0), occ, occ.astype(int),
                               rooms, {})
    assert e.value.errno == errno.ENOSPC and e.value.filename == str(full_disk / name)
    assert str(full_disk / name) in str(e.value)
    assert sorted(p.name for p in full_disk.iterdir()) == ["filler"]  # nothing half-written left


@pytest.mark.slow
def test_a_disk_that_fills_during_a_bag_segment_names_the_file(bag, tmp_path, capsys):
    """The outputs before the bag fit, the bag does not: the line names the bag file (a bare
    ``OSError: [Errno 28] No space left on device`` before)."""
    args = [f"bag={bag}", "bag_options.progress=false", "figure=false", "bag_options.out_format=ros1"]
    ref = tmp_path / "ref"
    assert segment.main([*args, f"out={ref}"]) == 0
    page = 4096
    pages = {p.name: -(-p.stat().st_size // page) * page for p in ref.iterdir()}
    before_bag, the_bag = sum(v for k, v in pages.items() if k != "segmentation.bag"), pages["segmentation.bag"]
    assert the_bag > 8 * page  # the bag is the largest output: it cannot fit in the room left below
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mnt)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({r.stderr.strip() or 'not root'})")
    try:
        st = os.statvfs(mnt)
        with open(mnt / "filler", "wb") as f:
            f.write(b"\0" * (st.f_bavail * st.f_frsize - before_bag - 4 * page))
        capsys.readouterr()
        assert segment.main([*args, f"out={mnt / 'out'}"]) == 2
        line = _one_line(capsys)
        assert "No space left on device" in line and f"{mnt}/" in line and "segmentation.bag" in line, line
        assert sorted(p.name for p in mnt.iterdir()) == ["filler"]  # no output folder, no temporary left
    finally:
        subprocess.run(["umount", "-l", str(mnt)], capture_output=True)
