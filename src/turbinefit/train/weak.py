"""Training on real photos labelled only with boxes, and on turbine-free photos.

Real photos come with boxes (one per turbine or blade, :mod:`turbinefit.io.regions`), not
with the skeleton the heat-maps draw. A box says two things, and the losses here use no
more than that:

* **Outside the box, nothing.** Every point and line channel is zero outside the box grown
  by a margin (:attr:`WeakPhotos.margin` of the box's size on each side, at least
  :data:`MIN_MARGIN_PX` map px): binary cross-entropy towards 0 there, each channel
  weighted as the renders' loss weights it (:func:`weak_loss`). These are the real
  negatives the renders lack: the roads, field edges, roofs and pylons of the photos.
  Turbine-free photos (``negatives``) are zero everywhere.
  Since a fit takes a single peak above its correspondence threshold for evidence, the
  largest logit of each channel over the known part is also pushed towards 0 (a
  negative bag of the multiple-instance term below).
* **Inside the box, some line.** Where the skeleton runs inside the box the box cannot
  tell, so no pixel inside it is pushed either way. A multiple-instance term asks only
  that the line channels' maximum over each of :attr:`WeakPhotos.strips` strips cut
  across the box's long side be high (cross-entropy of that maximum's logit towards 1):
  a turbine or blade box is crossed from end to end by its skeleton along its long side,
  so each third of it holds some line; a blade drawn only near its root, or an edge-on
  blade not drawn at all, is what the term punishes. Only boxes at least half in view
  ask for it.

The grown margin between the two (the band the net may draw in or not) takes the blade's
width and a loose box's slack. The points (base, tower top, hub, tips) have no term inside
a box: a box says neither whether nor where they are in view.

Each sample is one random view of a photo (:class:`WeakPhotos`): the photo letterboxed
into the net's 4:3 input as :func:`turbinefit.detect.letterbox` does (its reflected
margins hold mirrored parts of the turbine, so they are unknown for a photo with boxes),
or a random 4:3 window of 55-100 % of the largest the photo holds, then mirrored half
the time; :data:`THERMAL_SHARE` of the views of turbine-free photos are shown in false
colour, as thermal cameras show theirs. Photos are decoded once, at most :data:`DECODE_WIDTH` px wide.

Written here because no library trains heat-maps from boxes this way; the views use
:func:`turbinefit.io.images.resize_image` (Pillow).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch
from numpy.typing import NDArray
from torch.nn import functional as F

from turbinefit.eval.holdout import is_held_out
from turbinefit.eval.regions import LINE_CHANNELS
from turbinefit.geometry.camera import reduced_size
from turbinefit.io.images import check_image, list_images, read_image, resize_image
from turbinefit.io.regions import Box, RegionLabel, decode_rle, read_region_labels

#: Photos are decoded at most this wide (twice the shipped net's input: views of half
#: the photo keep their detail).
DECODE_WIDTH = 640
#: The box is grown by at least this many map px on each side before the outside is zero.
MIN_MARGIN_PX = 2.0
#: A box asks for line inside it only when at least this share of it is in the view.
MIN_IN_VIEW = 0.5
#: At most this many boxes of a photo ask for line (the rest are still unknown inside).
MAX_BOXES = 4
#: The starting net's line response above this counts as a line (:func:`attached_lines`).
ATTACHED_THRESHOLD = 0.3
#: Share of the views of turbine-free photos shown in false colour, as thermal cameras show
#: theirs (a thermal photo is no input a fit can use: it must find no turbine in it).
THERMAL_SHARE = 0.15
#: The false-colour palettes (matplotlib's names) of :func:`false_colour`.
THERMAL_PALETTES = ("inferno", "jet", "hot", "plasma")
#: Smallest and largest window of a random view, as a share of the largest 4:3 window.
VIEW_SCALE = (0.55, 1.0)


@dataclass(frozen=True)
class WeakPhoto:
    """A decoded photo and its boxes [px of ``image``, pixel edges]; none: a negative."""

    image: NDArray[np.uint8]
    boxes: tuple[Box, ...]
    name: str
    attached: NDArray[np.bool_] | None = None
    """Where the starting net's own lines run into a grown box (:func:`attached_lines`),
    on a grid covering the photo; None: nowhere."""


def _label_boxes(lab: RegionLabel) -> list[Box]:
    """Every box of a label; an outline or mask stands for its bounding box."""
    out = [b for _, b in lab.boxes]
    for _, xy in lab.polygons:
        xs, ys = xy[0::2], xy[1::2]
        out.append((min(xs), min(ys), max(xs), max(ys)))
    for _, rle in lab.rles:
        m = decode_rle(rle)
        rows, cols = np.flatnonzero(m.any(axis=1)), np.flatnonzero(m.any(axis=0))
        if rows.size:
            out.append((float(cols[0]), float(rows[0]), float(cols[-1] + 1), float(rows[-1] + 1)))
    return out


def _decode(path: Path) -> tuple[NDArray[np.uint8], float]:
    """(the photo at most :data:`DECODE_WIDTH` wide, its scale from the file's px)."""
    w0, h0 = check_image(path)
    w, h = reduced_size(w0, h0, DECODE_WIDTH)
    img = read_image(path, reduce_to=(w, h))
    if img.shape[1] != w:  # not a JPEG: read at its own size
        img = resize_image(img, w, h)
    return img, w / w0


def load_weak_photos(boxes: Sequence[Path], images_dir: Path | None,
                     negatives: Sequence[Path], hold_out: float
                     ) -> tuple[list[WeakPhoto], int]:
    """(the photos of the box files ``boxes`` (CSV or COCO, photos under ``images_dir``)
    and of the folders ``negatives``, decoded, leaving out those
    :func:`~turbinefit.eval.holdout.is_held_out` at ``hold_out``; how many were left out).
    Every label is read and checked (:func:`~turbinefit.io.regions.read_region_labels`)
    before any photo is decoded."""
    labels: list[tuple[Path, list[Box]]] = []
    for f in boxes:
        assert images_dir is not None
        for lab in read_region_labels(f, None, images_dir):
            lab.check_size(*check_image(lab.path))  # headers only, before any decoding
            labels.append((lab.path, _label_boxes(lab)))
    for folder in negatives:
        labels += [(p, []) for p in list_images([folder])]
    kept = [x for x in labels if not (hold_out > 0 and is_held_out(x[0].name, hold_out))]
    out = []
    for path, bxs in kept:
        img, s = _decode(path)
        out.append(WeakPhoto(img, tuple((x0 * s, y0 * s, x1 * s, y1 * s)
                                        for x0, y0, x1, y1 in bxs), path.name))
    return out, len(labels) - len(kept)


class WeakPhotos(torch.utils.data.Dataset[tuple[torch.Tensor, torch.Tensor, torch.Tensor]]):
    """Random views of box-labelled and turbine-free photos (module docstring): each item
    is (image (3, H, W) in [0, 1], known (1, h, w): 1 where every channel is known to be
    zero, strips (:data:`MAX_BOXES` x ``strips``, 4): (x0, y0, x1, y1) [map px, end
    exclusive] of each box strip that asks for line, -1 rows for none).

    ``input_size`` = (W, H) of the net's input, ``scale`` its ratio to the maps (h = H /
    scale). Randomness comes from torch's generator (seeded by the trainer)."""

    def __init__(self, photos: list[WeakPhoto], input_size: tuple[int, int], scale: int,
                 margin: float = 0.1, strips: int = 3) -> None:
        self.photos, self.input_size, self.scale = photos, input_size, scale
        self.margin, self.strips = margin, strips

    def __len__(self) -> int:
        return len(self.photos)

    def view(self, photo: WeakPhoto, letterboxed: bool, u: NDArray[np.float64]
             ) -> tuple[NDArray[np.uint8], tuple[float, float, float, float], Box]:
        """(input image, (x0, y0, sx, sy): photo px -> input px is (x - x0) * sx, and the
        input's area holding the photo (left, top, right, bottom) [input px]); ``u``:
        three uniform numbers in [0, 1) choosing the window."""
        iw, ih = self.input_size
        s = self.scale
        img = photo.image
        ph, pw = img.shape[:2]
        if letterboxed:
            f = min(iw / pw, ih / ph)
            rw = min(iw, s * max(1, round(pw * f / s)))
            rh = min(ih, s * max(1, round(ph * f / s)))
            small = resize_image(img, rw, rh)
            left, top = (iw - rw) // 2 // s * s, (ih - rh) // 2 // s * s
            pad = ((top, ih - rh - top), (left, iw - rw - left), (0, 0))
            canvas = small
            if (rw, rh) != (iw, ih):
                canvas = (np.pad(small, pad, mode="reflect") if min(rw, rh) > 1
                          else np.pad(small, pad, mode="edge"))
            return canvas, (-left * pw / rw, -top * ph / rh, rw / pw, rh / ph), \
                (left, top, left + rw, top + rh)
        cw_max = min(pw, ph * iw / ih)
        cw = cw_max * (VIEW_SCALE[0] + (VIEW_SCALE[1] - VIEW_SCALE[0]) * u[0])
        ch = cw * ih / iw
        x0, y0 = (pw - cw) * u[1], (ph - ch) * u[2]
        crop = resize_image(img, iw, ih, box=(x0, y0, x0 + cw, y0 + ch))
        return crop, (x0, y0, iw / cw, ih / ch), (0.0, 0.0, float(iw), float(ih))

    def targets(self, photo: WeakPhoto, xform: tuple[float, float, float, float],
                area: Box) -> tuple[NDArray[np.float32], NDArray[np.int64]]:
        """(known (h, w), strips) of a view (:meth:`view`'s transform and photo area)."""
        iw, ih = self.input_size
        s = self.scale
        w, h = iw // s, ih // s
        x0, y0, sx, sy = xform
        known = np.ones((h, w), dtype=bool)
        if photo.attached is not None:  # the starting net's lines running into a box
            ah, aw = photo.attached.shape
            ph, pw = photo.image.shape[:2]
            px = ((np.arange(w) + 0.5) * s / sx + x0) * aw / pw
            py = ((np.arange(h) + 0.5) * s / sy + y0) * ah / ph
            cols = np.clip(np.floor(px).astype(int), 0, aw - 1)
            rows = np.clip(np.floor(py).astype(int), 0, ah - 1)
            known &= ~photo.attached[rows[:, None], cols[None, :]]
        if photo.boxes:  # the reflected margins of a letterboxed photo with boxes: unknown
            a0, b0, a1, b1 = (v / s for v in area)
            uc, vc = np.arange(w) + 0.5, np.arange(h) + 0.5
            known &= ((vc >= b0) & (vc <= b1))[:, None] & ((uc >= a0) & (uc <= a1))[None, :]
        strips = np.full((MAX_BOXES * self.strips, 4), -1, dtype=np.int64)
        k = 0
        for bx0, by0, bx1, by1 in photo.boxes:
            # the box in map px (pixel edges)
            mx0, mx1 = (bx0 - x0) * sx / s, (bx1 - x0) * sx / s
            my0, my1 = (by0 - y0) * sy / s, (by1 - y0) * sy / s
            gx = max(self.margin * (mx1 - mx0), MIN_MARGIN_PX)
            gy = max(self.margin * (my1 - my0), MIN_MARGIN_PX)
            uc, vc = np.arange(w) + 0.5, np.arange(h) + 0.5
            known &= ~(((vc >= my0 - gy) & (vc <= my1 + gy))[:, None]
                       & ((uc >= mx0 - gx) & (uc <= mx1 + gx))[None, :])
            vx0, vy0 = max(mx0, area[0] / s), max(my0, area[1] / s)
            vx1, vy1 = min(mx1, area[2] / s), min(my1, area[3] / s)
            full = (mx1 - mx0) * (my1 - my0)
            seen = max(vx1 - vx0, 0.0) * max(vy1 - vy0, 0.0)
            if full <= 0 or seen < MIN_IN_VIEW * full or k >= len(strips) \
                    or vx1 - vx0 < 1 or vy1 - vy0 < 1:
                continue
            along_x = vx1 - vx0 >= vy1 - vy0
            lo, hi = (vx0, vx1) if along_x else (vy0, vy1)
            for j in range(self.strips):
                a0 = lo + (hi - lo) * j / self.strips
                a1 = lo + (hi - lo) * (j + 1) / self.strips
                r = (a0, vy0, a1, vy1) if along_x else (vx0, a0, vx1, a1)
                c0, r0 = math.floor(r[0]), math.floor(r[1])
                c1, r1 = max(math.ceil(r[2]), c0 + 1), max(math.ceil(r[3]), r0 + 1)
                strips[k] = (max(c0, 0), max(r0, 0), min(c1, w), min(r1, h))
                k += 1
        return known.astype(np.float32), strips

    def __getitem__(self, i: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        photo = self.photos[i]
        r = torch.rand(7).numpy().astype(np.float64)
        image, xform, area = self.view(photo, bool(r[0] < 0.5), r[1:4])
        if not photo.boxes and r[5] < THERMAL_SHARE:
            image = false_colour(image, r[6])
        known, strips = self.targets(photo, xform, area)
        if r[4] < 0.5:  # mirrored
            w = known.shape[1]
            image, known = image[:, ::-1], known[:, ::-1]
            ok = strips[:, 0] >= 0
            strips[ok, 0], strips[ok, 2] = w - strips[ok, 2], w - strips[ok, 0]
        x = torch.from_numpy(np.ascontiguousarray(image.transpose(2, 0, 1))).float() / 255.0
        return (x, torch.from_numpy(np.ascontiguousarray(known))[None],
                torch.from_numpy(strips))


def false_colour(image: NDArray[np.uint8], u: float) -> NDArray[np.uint8]:
    """``image``'s luminance through one of :data:`THERMAL_PALETTES` (chosen by ``u`` in
    [0, 1); its second half reverses the scale), as thermal cameras show their photos."""
    from matplotlib import colormaps

    k = int(u * 2 * len(THERMAL_PALETTES))
    lum = image.astype(np.float32) @ np.array([0.299, 0.587, 0.114], dtype=np.float32) / 255.0
    if k >= len(THERMAL_PALETTES):
        lum = 1.0 - lum
    rgb = colormaps[THERMAL_PALETTES[k % len(THERMAL_PALETTES)]](lum)[..., :3]
    return np.rint(rgb * 255.0).astype(np.uint8)


def attached_lines(photos: list[WeakPhoto], maps_of: Callable[[NDArray[np.uint8]], NDArray[np.floating]],
                   margin: float, threshold: float = ATTACHED_THRESHOLD) -> list[WeakPhoto]:
    """``photos`` with :attr:`WeakPhoto.attached` set: the connected regions (8-connected)
    of the starting net's line response above ``threshold`` that reach into a box grown
    by ``margin`` (``maps_of``: the net's maps (7, h, w) of a whole photo, on a grid
    covering it).

    A box covers one turbine, or one blade: the tower below a boxed blade, the blades a
    box leaves out and a turbine nobody boxed are not in it, and zero there would teach
    the net to miss them. Where the net's own lines run on from inside the box they are
    left unknown; lines it draws apart from every box (a road, a roof ridge, a pylon
    across the field) stay zero. A road the net draws into the box stays unknown too:
    the price of not erasing the turbine's own parts."""
    from scipy import ndimage

    out = []
    for ph in photos:
        if not ph.boxes:
            out.append(ph)
            continue
        maps = maps_of(ph.image)
        mh, mw = maps.shape[1:]
        H, W = ph.image.shape[:2]
        lines = maps[list(LINE_CHANNELS)].max(axis=0) > threshold
        labels = ndimage.label(lines, structure=np.ones((3, 3), dtype=bool))[0]
        near = np.zeros((mh, mw), dtype=bool)
        uc, vc = (np.arange(mw) + 0.5) * W / mw, (np.arange(mh) + 0.5) * H / mh
        for x0, y0, x1, y1 in ph.boxes:
            gx, gy = margin * (x1 - x0), margin * (y1 - y0)
            near |= (((vc >= y0 - gy) & (vc <= y1 + gy))[:, None]
                     & ((uc >= x0 - gx) & (uc <= x1 + gx))[None, :])
        hit = np.unique(labels[near & lines])
        attached = np.isin(labels, hit[hit > 0])
        out.append(replace(ph, attached=attached if attached.any() else None))
    return out


def weak_loss(logits: torch.Tensor, known: torch.Tensor, strips: torch.Tensor,
              channel_weights: tuple[float, ...] | None = None, mil_weight: float = 0.05
              ) -> tuple[torch.Tensor, float, float, float]:
    """(loss, its outside part, its in-box multiple-instance part, its outside-peak part)
    of ``logits`` (B, 7, h, w) of box-labelled or turbine-free photos (module docstring):

    * cross-entropy towards 0 where ``known`` (B, 1, h, w) is 1, channel-weighted and
      averaged over every element as the renders' loss is (a pixel that is not known adds
      nothing);
    * ``mil_weight`` times the mean over the ``strips`` (B, S, 4) of the cross-entropy
      towards 1 of the line channels' largest logit in the strip (a positive bag: some
      pixel of it is line);
    * ``mil_weight`` times the channel-weighted mean over the photos and channels of the
      cross-entropy towards 0 of each channel's largest logit where ``known`` (a negative
      bag: no pixel of it is anything). The per-pixel term barely sees a few false peaks
      among 19,200 pixels; this one sees only them, and a fit takes one peak above its
      correspondence threshold for evidence."""
    cw = (torch.ones(logits.shape[1], dtype=logits.dtype) if channel_weights is None
          else torch.tensor(channel_weights, dtype=logits.dtype))
    outside = (F.softplus(logits) * known * cw.view(1, -1, 1, 1)).mean()
    line = logits[:, list(LINE_CHANNELS)].amax(dim=1)
    peaks = []
    for b in range(strips.shape[0]):
        for x0, y0, x1, y1 in strips[b].tolist():
            if x0 >= 0:
                peaks.append(line[b, y0:y1, x0:x1].amax())
    mil = F.softplus(-torch.stack(peaks)).mean() if peaks else logits.new_zeros(())
    bags = known.flatten(1).amax(dim=1) > 0
    if bool(bags.any()):
        top = logits.masked_fill(known < 0.5, -1e4).flatten(2).amax(dim=2)[bags]
        peak = (F.softplus(top) * cw).mean()
    else:
        peak = logits.new_zeros(())
    return (outside + mil_weight * (mil + peak), float(outside.detach()), float(mil.detach()),
            float(peak.detach()))
