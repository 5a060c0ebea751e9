"""Labels and images in: the labels-file classifier (names or probabilities, class list from
the config or the file, matching by order, id or pose) and the image-folder renderer (a pose
file listing images, in the ROS or simulator frame), with hand-worked answers."""

import json
import math

import numpy as np
import pytest
from PIL import Image

from benchmark.classifiers.labels_file import LabelsFileClassifier
from benchmark.interfaces import Classifier, Renderer
from envs.maps.gridmap import GridMap
from envs.render.image_folder import ImageFolderRenderer, match_poses
from envs.render.observation import Observation

try:
    import torch
    import torchvision  # noqa: F401
except ImportError:
    torch = None


def _obs(poses, ids=None):
    ids = ids or [None] * len(poses)
    return [Observation(pose=tuple(map(float, p)), meta=({"id": i} if i is not None else {})) for p, i in zip(poses, ids)]


# ---------------------------------------------------------------- labels file


def test_names_with_configured_classes_give_one_hot_rows_in_view_order(tmp_path):
    f = tmp_path / "labels.csv"
    f.write_text("label\nkitchen\n bedroom \nkitchen\n")
    clf = LabelsFileClassifier(str(f), classes=["bedroom", "kitchen", "bathroom"])
    assert isinstance(clf, Classifier)
    p = clf.predict_proba(_obs([(0, 0, 0)] * 3))
    assert p.tolist() == [[0, 1, 0], [1, 0, 0], [0, 1, 0]]
    assert clf.classes == ("bedroom", "kitchen", "bathroom")


def test_open_label_set_takes_the_sorted_names_of_the_file(tmp_path):
    f = tmp_path / "labels.json"
    f.write_text(json.dumps({"labels": [{"label": "office"}, {"label": "lab"}, {"label": "server room"},
                                        {"label": "office"}]}))
    clf = LabelsFileClassifier(str(f), classes=None)
    assert clf.classes == ("lab", "office", "server room")
    assert np.argmax(clf.predict_proba(_obs([(0, 0, 0)] * 4)), axis=1).tolist() == [1, 0, 2, 1]


def test_unknown_names_are_one_line_naming_them_and_the_file(tmp_path):
    f = tmp_path / "labels.csv"
    f.write_text("label\nkitchen\noffice\nlab\noffice\n")
    with pytest.raises(ValueError) as e:
        LabelsFileClassifier(str(f), classes=["kitchen", "bedroom"]).predict_proba(_obs([(0, 0, 0)] * 4))
    msg = str(e.value)
    assert "\n" not in msg and str(f) in msg and "'label'" in msg and "['lab', 'office']" in msg
    assert "rows [1, 2, 3]" in msg


def test_probability_columns_are_normalised_and_ordered_by_the_class_list(tmp_path):
    f = tmp_path / "p.csv"
    f.write_text("id,Kitchen,bedroom\na,1,3\nb,2,0\n")
    clf = LabelsFileClassifier(str(f), classes=["bedroom", "kitchen"], match="order")
    assert np.allclose(clf.predict_proba(_obs([(0, 0, 0)] * 2)), [[0.75, 0.25], [0.0, 1.0]])
    # the class list from the file: its probability columns, in file order (id is not a class)
    assert LabelsFileClassifier(str(f)).classes == ("kitchen", "bedroom")


@pytest.mark.parametrize("text,classes,expect", [
    ("kitchen,office\n1,0\n", ["kitchen"], r"column\(s\) \['office'\] are not in the class list"),
    ("kitchen\n1\n", ["kitchen", "bedroom"], r"lacks probability column\(s\) \['bedroom'\]"),
    ("kitchen,bedroom\n-1,2\n", None, r"column 'kitchen' has -1.0 at row 0; expected a probability >= 0"),
    ("kitchen,bedroom\n0,0\n", None, r"row 0 has probabilities summing to 0.0"),
    ("kitchen,bedroom\nx,1\n", None, r"column 'kitchen' has 'x' at row 0"),
    ("id,x\n1,2\n", None, r"no 'label' column and no probability columns"),
])
def test_bad_probability_files_are_one_line_naming_the_file(tmp_path, text, classes, expect):
    f = tmp_path / "p.csv"
    f.write_text(text)
    with pytest.raises(ValueError, match=expect) as e:
        LabelsFileClassifier(str(f), classes=classes, match="order").predict_proba(_obs([(0, 0, 0)]))
    assert str(f) in str(e.value) and "\n" not in str(e.value)


def test_match_by_id_follows_the_views_not_the_file_order(tmp_path):
    f = tmp_path / "labels.csv"
    f.write_text("id,label\nv2,bedroom\nv0,kitchen\nv1,bathroom\n")
    clf = LabelsFileClassifier(str(f), classes=["bathroom", "bedroom", "kitchen"])
    obs = _obs([(0, 0, 0)] * 3, ids=["v0", "v1", "v2"])
    assert clf.match_mode(clf.read()[0], obs) == "id"
    assert np.argmax(clf.predict_proba(obs), axis=1).tolist() == [2, 0, 1]
    with pytest.raises(ValueError, match=r"no row for view id\(s\) \['v9'\]"):
        clf.predict_proba(_obs([(0, 0, 0)], ids=["v9"]))


def test_match_by_pose_in_the_ros_frame(tmp_path):
    # ROS (x=1, y=2, theta=pi/2) faces +y = project yaw 0; theta=0 faces +x = yaw 90
    f = tmp_path / "labels.csv"
    f.write_text(f"x,y,theta,label\n1,2,{math.pi / 2},kitchen\n1,2,0,bedroom\n-3,0.5,{math.pi},bathroom\n")
    clf = LabelsFileClassifier(str(f), classes=["bathroom", "bedroom", "kitchen"], frame="ros")
    obs = _obs([(-3, 0.5, 270.0), (1, 2, 90.0), (1.0004, 2, 359.8)])
    assert clf.match_mode(clf.read()[0], obs) == "pose"
    assert np.argmax(clf.predict_proba(obs), axis=1).tolist() == [0, 1, 2]
    with pytest.raises(ValueError, match=r"no row within 0.001 m and 0.5 degrees of view 0 at x=1.0000, z=2.0000, "
                                         r"yaw=45.00"):
        clf.predict_proba(_obs([(1, 2, 45.0)]))
    # in the simulator frame the same file has no z / yaw columns: auto falls back to row order
    sim = LabelsFileClassifier(str(f), classes=["bathroom", "bedroom", "kitchen"], frame="sim")
    assert sim.match_mode(sim.read()[0], obs) == "order"


def test_match_by_order_needs_one_row_per_view(tmp_path):
    f = tmp_path / "labels.csv"
    f.write_text("label\nkitchen\nkitchen\n")
    with pytest.raises(ValueError, match=r"2 rows for 3 views \(match=order"):
        LabelsFileClassifier(str(f)).predict_proba(_obs([(0, 0, 0)] * 3))


def test_house_template_reads_each_house_file(tmp_path):
    (tmp_path / "h1.csv").write_text("label\nkitchen\n")
    (tmp_path / "h2.csv").write_text("label\nbedroom\n")
    clf = LabelsFileClassifier(str(tmp_path / "{house_id}.csv"), classes=["bedroom", "kitchen"])
    one = [Observation(pose=(0, 0, 0), meta={"house_id": "h2"})]
    assert clf.predict_proba(one).tolist() == [[1.0, 0.0]]
    with pytest.raises(ValueError, match="give classifier.classes too"):
        LabelsFileClassifier(str(tmp_path / "{house_id}.csv"))
    with pytest.raises(ValueError, match=r"needs every view's meta\['house_id'\]"):
        clf.predict_proba(_obs([(0, 0, 0)]))


def test_labels_config_builds_the_classifier(tmp_path):
    from hydra import compose, initialize_config_dir
    from hydra.utils import instantiate

    from benchmark.paths import CONF_DIR

    f = tmp_path / "labels.csv"
    f.write_text("label\nkitchen\n")
    with initialize_config_dir(config_dir=CONF_DIR, version_base="1.3"):
        cfg = compose("config", overrides=["classifier=labels", f"classifier.path={f}"])
    clf = instantiate(cfg.classifier)
    assert clf.classes == tuple(cfg.classes) and clf.predict_proba(_obs([(0, 0, 0)])).shape == (1, 7)


# ---------------------------------------------------------------- image folder


def _write_views(folder, frame="ros"):
    """Three 4 x 5 images of one colour each and a pose file naming them."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "pics").mkdir()
    colours = [(255, 0, 0), (0, 255, 0), (0, 0, 255)]
    for i, c in enumerate(colours):
        Image.fromarray(np.full((4, 5, 3), c, np.uint8)).save(folder / "pics" / f"v{i}.png")
    if frame == "ros":
        rows = ["image,x,y,theta", f"pics/v0.png,1,2,{math.pi / 2}", "pics/v1.png,1,2,0", f"pics/v2.png,-3,0.5,{math.pi}"]
    else:
        rows = ["image,x,z,yaw", "pics/v0.png,1,2,0", "pics/v1.png,1,2,90", "pics/v2.png,-3,0.5,270"]
    (folder / "views.csv").write_text("\n".join(rows) + "\n")
    return folder / "views.csv", colours


@pytest.mark.parametrize("frame", ["ros", "sim"])
def test_image_folder_reads_images_and_converts_poses(tmp_path, frame):
    poses, colours = _write_views(tmp_path, frame)
    r = ImageFolderRenderer(str(poses), frame=frame)
    assert isinstance(r, Renderer)
    obs = r.observations()
    assert [o.pose for o in obs] == [(1.0, 2.0, 0.0), (1.0, 2.0, 90.0), (-3.0, 0.5, 270.0)]
    for o, c in zip(obs, colours):
        assert o.image.shape == (4, 5, 3) and o.image.dtype == np.uint8 and (o.image == c).all()
    assert [o.meta["id"] for o in obs] == ["pics/v0.png", "pics/v1.png", "pics/v2.png"]


def test_render_returns_the_views_at_the_requested_poses(tmp_path):
    poses, colours = _write_views(tmp_path)
    r = ImageFolderRenderer(str(poses), frame="ros")

    class _Scene:
        house_id = "h"
        grid = GridMap(np.ones((4, 4), bool), 1.0, (-5.0, 5.0))

    obs = r.render(None, _Scene(), np.array([[-3, 0.5, 270.0], [1, 2, 0.2]]))
    assert [tuple(o.image[0, 0]) for o in obs] == [colours[2], colours[0]]
    assert obs[0].meta["house_id"] == "h"
    with pytest.raises(ValueError, match=r"no view within .* of pose 0 at x=1.0000, z=2.0000, yaw=180.00"):
        r.render(None, _Scene(), np.array([[1, 2, 180.0]]))


def test_match_poses_by_hand():
    listed = np.array([[0, 0, 0], [0, 0, 359.9], [1, 0, 90]])
    assert match_poses(listed, np.array([[0, 0, 0.2], [1.0005, 0, 90.4], [1, 0, 270]]), 1e-3, 0.5) == [[0, 1], [2], []]


def test_missing_image_is_one_line_naming_it_the_file_and_the_row(tmp_path):
    poses, _ = _write_views(tmp_path)
    (tmp_path / "pics" / "v1.png").unlink()
    with pytest.raises(FileNotFoundError) as e:
        ImageFolderRenderer(str(poses), frame="ros").observations()
    msg = str(e.value)
    assert "\n" not in msg and str(poses) in msg and "column 'image' row 1" in msg and "'pics/v1.png'" in msg
    assert "1 of 3 images missing" in msg


def test_pose_file_without_image_column_or_with_wrong_pose_columns(tmp_path):
    f = tmp_path / "views.csv"
    f.write_text("x,y,theta\n1,2,0\n")
    with pytest.raises(ValueError, match=r"no 'image' column naming each view's image"):
        ImageFolderRenderer(str(f), frame="ros").observations()
    with pytest.raises(ValueError, match=r"lacks column\(s\) \['z', 'yaw'\] for frame 'sim'"):
        ImageFolderRenderer(str(f), frame="sim").observations()


def test_images_folder_option_and_id_column(tmp_path):
    poses, colours = _write_views(tmp_path / "a")
    text = poses.read_text().replace("pics/", "").replace("image,", "image,")
    lines = text.strip().splitlines()
    lines = ["id," + lines[0]] + [f"view{i}," + ln for i, ln in enumerate(lines[1:])]
    f = tmp_path / "b.csv"
    f.write_text("\n".join(lines) + "\n")
    obs = ImageFolderRenderer(str(f), frame="ros", folder=str(tmp_path / "a" / "pics")).observations()
    assert [o.meta["id"] for o in obs] == ["view0", "view1", "view2"] and (obs[1].image == colours[1]).all()


@pytest.mark.slow
@pytest.mark.skipif(torch is None, reason="torch/torchvision not installed")
def test_a_cnn_classifies_the_folder_images(tmp_path):
    from benchmark.classifiers.cnn import CNNClassifier

    poses, _ = _write_views(tmp_path)
    obs = ImageFolderRenderer(str(poses), frame="ros").observations()
    torch.manual_seed(0)
    clf = CNNClassifier(["a", "b"], arch="resnet18", pretrained=False, device="cpu", image_size=32,
                        allow_untrained=True)
    p = clf.predict_proba(obs)
    assert p.shape == (3, 2) and np.allclose(p.sum(1), 1)
    assert np.allclose(p, clf.predict_images([o.image for o in obs]), atol=1e-6)
