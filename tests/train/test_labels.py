"""Training labels (turbinefit.train.labels): COCO labels give the rendered targets.

Needs the optional extra ``turbinefit[train]``; skipped without PyTorch."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from support import photo_px

torch = pytest.importorskip("torch")
pytest.importorskip("onnx")

from turbinefit.io.coco import LabelledImage, TurbineKeypoints, write_coco_keypoints  # noqa: E402
from turbinefit.io.images import write_png  # noqa: E402
from turbinefit.sim.dataset import DatasetSpec, render_sample  # noqa: E402
from turbinefit.train.labels import labelled_sample  # noqa: E402

torch.set_num_threads(1)


def test_coco_labels_give_the_rendered_targets(tmp_path: Path) -> None:
    """A rendered sample exported as a COCO file and imported again gives its own targets."""
    spec = DatasetSpec(1, seed=0)
    s_ = spec.image_scale
    images = []
    for i in range(12):
        s = render_sample(spec, i)
        if s.visible.sum() >= 5:
            images.append((i, s))
        if len(images) == 2:
            break
    assert images, "no view with the turbine in view"
    labelled = []
    for i, s in images:
        write_png(tmp_path / f"{i}.png", s.image)
        labelled.append(LabelledImage(tmp_path / f"{i}.png", spec.width * s_, spec.height * s_, (
            TurbineKeypoints(photo_px(s.points, s_), np.where(s.visible, 2, 0).astype(np.int8)),)))
    write_coco_keypoints(labelled, tmp_path / "labels.json", tmp_path)
    from turbinefit.io.coco import read_coco_keypoints

    back = read_coco_keypoints(tmp_path / "labels.json", tmp_path)
    for (_, s), item in zip(images, back, strict=True):
        img, tgt = labelled_sample(item, spec.width, spec.height, spec.sigma_px, s_)
        np.testing.assert_array_equal(img, s.image)
        vis = s.visible
        # points: identical blobs for the labelled (visible) points
        for c in (0, 1, 2):
            if vis[c]:
                np.testing.assert_allclose(tgt[c] / 255.0, s.target[c], atol=0.01)
        # lines between two visible points: the same ridge
        for a, b, c in ((0, 1, 4), (1, 2, 5)):
            if vis[a] and vis[b]:
                np.testing.assert_allclose(tgt[c] / 255.0, s.target[c], atol=0.02)
