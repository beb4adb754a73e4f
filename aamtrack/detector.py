"""Face localisation for the first frame and after a loss (poster, "Face localization"): OpenCV's Haar
frontal face detector (the cascade shipped in the opencv wheel), the largest face, and a rough pose fitted to
feature points guessed from the box. Where the points sit in a Haar box is learned at training time
(``aamtrack.train.detection``: mean of the annotated landmarks in box units over the training images)."""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path
from typing import NamedTuple

import cv2
import numpy as np

from .errors import InputError

log = logging.getLogger(__name__)

CASCADES = ("haarcascade_frontalface_default.xml",  # the detector's own
            "haarcascade_frontalface_alt2.xml")     # a second opinion on faces the first misses (``find``)
MIN_NEIGHBORS = (4, 3)  # per cascade: overlapping hits a face needs (alt2's usual 3)
DETECT_WIDTH = 320  # frames are detected at about this width (faster; faces over ~25% of the width)
EQUALIZE_CLIP = 4.0  # clipped equalisation: no grey level counts for more than this many times an even share
LOCAL_CLIP, LOCAL_TILES = 4.0, 4  # local (CLAHE) equalisation: clip limit, tiles per side
EQUALIZATIONS = ("plain", "clipped", "local")
SAME_BOX = 0.3  # boxes overlapping by more than this (intersection over union) are one face


ROLLED = (30.0, -30.0)  # degrees the frame is also turned by when no upright face is found


class Search(NamedTuple):
    """One of ``HaarDetector.find``'s searches: ``detect_all``'s arguments, ``detect_all(gray, **s._asdict())``."""

    angle: float = 0.0
    width: int = DETECT_WIDTH
    equalize: str = "plain"
    cascade: int = 0
    smallest: bool = False
    close: bool = False
    edge: bool = False


def box_order(boxes: np.ndarray, hits: np.ndarray | None = None) -> np.ndarray:
    """Indices that order boxes (n, 4) (x, y, w, h) largest first, or with hits (n,) most hits first and then
    largest, ties broken by position (left first, then top): one order whatever order OpenCV's threads return
    the boxes in (sorted by area alone, equal boxes came in any order: the suspect when two trainings differed
    in one textured negative, 2026-12-01)."""
    keys = (boxes[:, 1], boxes[:, 0], -boxes[:, 2] * boxes[:, 3])
    return np.lexsort(keys if hits is None else (*keys, -np.asarray(hits)))


class HaarDetector:
    """``detect(gray)`` -> (x, y, w, h) float box of the largest face in pixels, or None; ``find(gray)`` also
    looks for faces rolled by about 30 degrees (the frontal cascade misses them), in turned copies of the frame,
    and for faces under uneven light; ``more(gray, tried)`` gives other boxes when the first one's fit failed."""

    def __init__(self, *, min_face_fraction: float = 0.08, scale_factor: float = 1.1, min_neighbors: int = 4,
                 rolled: tuple = ROLLED):
        self.cascades = []
        for name in CASCADES:
            path = Path(cv2.data.haarcascades) / name
            cascade = cv2.CascadeClassifier(str(path))
            if cascade.empty():
                raise InputError(f"{path}: cannot load OpenCV's Haar face cascade (opencv wheel without cascades?)")
            self.cascades.append(cascade)
        self.cascade = self.cascades[0]
        self.min_face_fraction = min_face_fraction
        self.scale_factor = scale_factor
        self.min_neighbors = (min_neighbors,) + MIN_NEIGHBORS[1:]
        self.rolled = tuple(rolled)

    def detect_all(self, gray: np.ndarray, angle: float = 0.0, width: int = 0, *, equalize: str = "plain",
                   cascade: int = 0, smallest: bool = False, close: bool = False, edge: bool = False) -> np.ndarray:
        """(n, 4) float boxes (x, y, w, h), largest first, in the frame turned by ``angle`` degrees
        (counterclockwise on screen) about its centre (``unturn`` maps points back), searched at ``width``
        pixels wide at most (default ``DETECT_WIDTH``) by cascade ``cascade`` of ``CASCADES``, after histogram
        equalisation: ``equalize`` "plain" (``cv2.equalizeHist``), "clipped" (``equalize_clipped``) or "local"
        (CLAHE, ``LOCAL_CLIP`` on ``LOCAL_TILES`` x ``LOCAL_TILES`` tiles). Boxes are at least
        ``min_face_fraction`` of the searched image's shorter side, or, with ``smallest``, as small as the
        cascade's own window (``SMALLEST_BOX``), and then come strongest first (most of the cascade's
        overlapping hits), not largest first: at those sizes a textured background gives boxes too (a face 30 px
        between the eyes in a dark textured 1920x1080 frame: 3 boxes a frame, the face's the largest in 1 of 37
        frames and the strongest in 32). With ``close``, only boxes of at least ``CLOSE_MIN`` of the frame's
        shorter side, searched in the frame with its edges replicated ``CLOSE_PAD`` of that side outwards: a
        close-up whose box reaches past the frame's edge (``CLOSE_PAD``'s note); such boxes may lie partly
        outside the frame. With ``edge``, the same padded frame searched for boxes of any size: a face of any
        size cut by the frame's edge (the note "Edges" before ``CLOSE_PAD``)."""
        if gray.ndim == 3:
            gray = cv2.cvtColor(gray, cv2.COLOR_BGR2GRAY)
        if gray.dtype != np.uint8:
            gray = np.clip(gray, 0, 255).astype(np.uint8)
        f = min(1.0, (width or DETECT_WIDTH) / gray.shape[1])
        small = cv2.resize(gray, None, fx=f, fy=f, interpolation=cv2.INTER_AREA) if f < 1 else gray
        if equalize == "plain":
            small = cv2.equalizeHist(small)
        elif equalize == "clipped":
            small = equalize_clipped(small)
        elif equalize == "local":
            small = cv2.createCLAHE(clipLimit=LOCAL_CLIP, tileGridSize=(LOCAL_TILES, LOCAL_TILES)).apply(small)
        else:
            raise ValueError(f"equalize {equalize!r}: one of {', '.join(EQUALIZATIONS)}")
        m = SMALLEST_BOX if smallest else max(SMALLEST_BOX, int(self.min_face_fraction * min(small.shape)))
        if close:
            m = max(m, int(CLOSE_MIN * min(small.shape)))
        pad = int(round(CLOSE_PAD * min(small.shape))) if close or edge else 0
        if pad:
            small = cv2.copyMakeBorder(small, pad, pad, pad, pad, cv2.BORDER_REPLICATE)
        if angle:
            h, w = small.shape
            M = cv2.getRotationMatrix2D((w / 2, h / 2), angle, 1.0)
            small = cv2.warpAffine(small, M, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        boxes, hits = self.cascades[cascade].detectMultiScale2(small, scaleFactor=self.scale_factor,
                                                               minNeighbors=self.min_neighbors[cascade], minSize=(m, m))
        if len(boxes) == 0:
            return np.zeros((0, 4))
        boxes = np.asarray(boxes, float)
        boxes[:, :2] -= pad
        boxes /= f
        # strongest first with ``smallest``: at the smallest sizes the background gives boxes too, with fewer hits
        return boxes[box_order(boxes, np.asarray(hits, float).ravel() if smallest else None)]

    def detect(self, gray: np.ndarray):
        boxes = self.detect_all(gray)
        return boxes[0] if len(boxes) else None

    def find(self, gray: np.ndarray, *, thorough: bool = True) -> tuple[np.ndarray, float] | None:
        """(box, angle): the first box of these searches, in order: the largest upright face; the largest upright
        one at up to twice the detection width after clipped histogram equalisation (small faces); the largest
        in the frame turned by each of ``rolled`` degrees (the box is in that turned frame: ``unturn`` maps points
        back); the largest upright one at up to twice the detection width after local (CLAHE) equalisation (small
        faces again); the largest close-up, its box reaching past the frame's edges (``CLOSE_PAD``); and, when
        ``thorough``, the largest upright one after local equalisation (``UNEVEN``: uneven light), the largest
        cut by the frame's edge (the note "Edges" before ``CLOSE_PAD``), the largest in the frame turned by each of
        ``rolled`` degrees at up to twice the detection width after local equalisation (the note "Small rolled
        faces" there), then the smallest faces after local equalisation too (``SMALLEST_WIDTHS``, then with the
        second cascade). None when there is none: a frame without a face costs all of these searches, the
        thorough ones most (``TrackerConfig.thorough_every`` has the figures).

        The second search is for small faces, which a plain equalisation hides wherever a flat background fills
        most of the frame: its grey level takes most of the output range, and the face's contrast is squeezed
        into a few levels either side (helen_test shrunk to 30 px between the outer eye corners in a grey frame:
        Haar finds 225 of 330 after equalisation, 311 without, 312 after the clipped one; twice the detection
        width: on cap12 shrunk the same way, 20 of 60 frames found against 0). The first search keeps the plain
        equalisation, which finds more overexposed faces (helen_test x2.2 clipped: 309 against 298).
        The fifth, after local equalisation, finds many small faces the clipped one misses (a tile's histogram is
        mostly the face's own surroundings; see ``SMALLEST_WIDTHS``' note). It runs after the others, not instead
        of the clipped one: in its place, the same faces shrunk to 30 px between the eyes in a grey 1280x720 frame
        were found by these searches 163 -> 223 times of 330, but helen_test stills lost a few images under
        noise, low contrast and overexposure (``benchmarks/robustness.py``, 3D: clean 98.5% -> 98.2%, noise 97.0%
        -> 96.4%, overexposed 91.8% -> 91.5% within NME 0.08, small30 96.4% -> 97.0%). Placed last it only runs
        where the others found nothing: on a lost track, every frame (1280x720, a face 24 px between the eyes,
        dim, slow pan and roll, a /tmp clip from cap12: 3D 276 -> 297 of 300 frames tracked, NME 0.0368 ->
        0.0379, none above 0.06; 2D 264 -> 275). helen_test stills as they were but dim_small 77.0% -> 77.3%;
        the video rows the same. ``more`` gives its boxes too: in ``benchmarks/still_shots.py`` one shot of 40
        now follows the mirrored copy of its face that the frame's reflected border shows (its fit of the right
        face had been 0.09 off: 60 more frames above 0.10, none fewer within 0.08). Its cost, on every lost
        frame without a face: the quick searches of a dim noisy room 163 -> 186 ms at 640x480, 132 -> 151 ms at
        1280x720 (medians, one core)."""
        for search in self._searches(gray.shape[1], thorough):
            boxes = self.detect_all(gray, **search._asdict())
            if len(boxes):
                return boxes[0], search.angle
        return None

    def _searches(self, frame_width: int, thorough: bool = True) -> list[Search]:
        """``find``'s searches, in order, for a frame this wide."""
        tries = [Search(), Search(width=2 * DETECT_WIDTH, equalize="clipped")]
        tries += [Search(angle=angle) for angle in self.rolled]
        tries += [Search(width=2 * DETECT_WIDTH, equalize="local")]
        tries += [Search(close=True)]  # a close-up past the frame's edges
        if not thorough:
            return tries
        tries += [Search(equalize=equalize, cascade=cascade) for equalize, cascade in UNEVEN]
        tries += [Search(edge=True)]  # a face of any size cut by the frame's edge
        tries += [Search(angle=angle, width=2 * DETECT_WIDTH, equalize="local") for angle in self.rolled]  # small
        widths = smallest_widths(frame_width)
        smallest = [Search(width=width, equalize="local", smallest=True) for width in widths]
        return tries + smallest + [Search(width=widths[-1], equalize="local", cascade=1, smallest=True)]  # alt2

    def more(self, gray: np.ndarray, tried=()) -> Iterator[np.ndarray]:
        """Upright boxes other than ``tried`` ((x, y, w, h) upright boxes whose fits failed), best guesses first:
        the plain search's smaller boxes, then the first two of each of ``find``'s other upright searches (in its
        order). A box overlapping one already given or tried by more than ``SAME_BOX`` (intersection over union)
        is skipped. Each search runs only when the boxes before it are used up."""
        seen = [np.asarray(b, float) for b in tried]
        searches = [(search, slice(0, 2)) for search in self._searches(gray.shape[1]) if search.angle == 0.0]
        searches[0] = (searches[0][0], slice(1, 3))  # the first search's largest box is what ``find`` gave
        for search, which in searches:
            for box in self.detect_all(gray, **search._asdict())[which]:
                if all(overlap(box, other) <= SAME_BOX for other in seen):
                    seen.append(box)
                    yield box


# Searches for faces under uneven light (a stage light from one side, overexposure): local (tile-wise, contrast
# limited) equalisation brings both halves of a half-lit face back to a face's contrast, where a plain one leaves
# its dark half dark; and OpenCV's alt2 cascade, a second opinion on the same image (its boxes sit where the first
# cascade's do: over 523 helen_train faces both found, median centre offset 0.002 / -0.004 box widths, width
# ratio 0.97, so the box-to-landmarks map learned for the first serves both). helen_test stills, shipped 3D model,
# with both searches in ``find`` and ``more``: fitted within NME 0.08 of all 330, lit from one side 83.9% -> 93.6%,
# overexposed 90.6% -> 92.1%, blurred 77.6% -> 79.4%, clean 97.6% -> 98.2% (benchmarks/robustness.py).
UNEVEN = (("local", 0), ("local", 1))

# Searches for the smallest faces, last: boxes down to the cascade's own window (20 px), at 2, 4 and 6 times the
# detection width, never wider than the frame (measured first with clipped equalisation; now local: below).
# Haar's window is fixed in pixels and the other searches run on the frame shrunk to 320 or 640 px wide with
# boxes of at least 8% of its height: a face 40 px between the outer eye corners in a 1920x1080 frame is 7 px at
# 320 wide. helen_test faces shrunk to that eye
# distance, centred in a grey frame (60 faces, found upright with the box on the face), with the searches at 640
# and 1280 px: 40 px in 1920x1080: 10 -> 43; 30 px in 1920x1080: 0 -> 30, in 1280x720: 23 -> 44; 24 px in
# 1280x720: 4 -> 39; 16 px in 640x480: 6 -> 30 (40 px in 640x480: 60 both). ``benchmarks/robustness.py``'s
# small30_hd (all 330 stills, fitted within NME 0.08): 0% before, 55.5% with those two, 73.9% with the third at
# 1920 px. Capping each search's boxes at 50 px (a search per size band, about half the cost) found fewer
# (51.5%): Haar's hits on a face come from several neighbouring scales.
# Then, last, the second cascade (alt2) at the widest of those widths: the first one's smallest searches miss many
# faces that small that alt2 finds, and put no box elsewhere on them (small30_hd: of the 79 stills ``find``
# missed, alt2 at full width found 34, all on the face; at 1280 px 17, at 640 none; the first cascade at full
# width with fewer neighbours: 6 (3), 12 (2)). small30_hd 73.9% -> 84.2% within NME 0.08; a frame without a face
# costs its thorough searches about a quarter to a half more (cap12's background at 1920x1080: 0.79 -> 1.02 s,
# 640x480: 0.26 -> 0.41 s, dark noise at 1280x720: 1.3 -> 2.1 s; every ``thorough_every`` lost frames).
# All of these smallest-face searches equalise locally (CLAHE, as ``UNEVEN``), not with the clipped global
# histogram they first used: a small face is a few of a large frame's pixels, and a global equalisation, clipped or
# not, spends the output range on the rest of the frame, where CLAHE's tile spreads the face's own grey levels.
# helen_test's 330 photos shrunk into a grey frame, found upright with the box on the face (``find``, clipped ->
# local): 30 px between the eyes in 1920x1080 285 -> 320, 24 px in 1280x720 282 -> 314, 16 px in 640x480
# 234 -> 289, 30 px in 640x480 315 -> 326; 60 pasted at random places into cap12's room (its face inpainted away)
# at 1920x1080: 46 -> 55, with a box on 4 of 60 empty room frames either way. small30_hd 84.2% -> 94.2% within
# NME 0.08; small30 95.8% -> 96.4%; a thorough search of a frame without a face costs about the same (the room
# at 1920x1080: 0.84 -> 0.88 s).
# Close-ups: a face filling the frame, its chin or brow at the frame's edge, as webcams, phones and video calls
# frame a talking head. Haar's box reaches past the face's outline (about the brows to below the chin) and must
# lie inside the searched image, so such a face is not found at all, however clear. The frame's edge rows and
# columns replicated outwards give the box room. Measured 2026-11-29 (shipped 3D model, /tmp script: cap12
# zoomed about its face so the 68 landmarks' height is 0.9 / 1.0 / 1.1 / 1.2 of the frame's, tracked as ``aamtrack
# run`` tracks): tracked frames 87.7% / 46.9% / 33.7% / 72.1% -> 100% / 100% / 95.4% / 73.0% (NME 0.0202 / 0.0215 /
# 0.0241 / 0.0308; at 0.8 100% either way); of 134 frames at 0.9 ``find`` found 31 -> 128. Searched after the
# other quick searches, it changes nothing where they find a face: the robustness suite's video rows, hard clips,
# still shots and helen_test (3D 0.0339, 98.5% within 0.08) the same; of its still variants' 4,620 photos (and
# mirrors) 8 reach it with a box, one of them crossing NME 0.08 (overexposed: 0.0793 -> 0.088). A frame without a
# face costs about 1-4 ms more (grey or noisy 640x480 and 1280x720, quick searches: 24-355 ms before).
# Edges: a face of any size cut by the frame's side (a speaker at the edge of a stage shot, a person leaning out
# of a webcam's view) has no box inside the frame either; the close-up's padded frame, searched for boxes of any
# size, gives it one. Measured 2026-11-30 (shipped 3D model, /tmp script: cap12's first 300 frames moved left so
# 15% / 30% of the face's width lies past the frame's left edge, tracked as ``aamtrack run`` tracks): tracked
# 88.0% / 0% -> 98.7% / 98.7% (NME over the visible points 0.0306 -> 0.0298 / 0.0357; over all 68, the hidden
# ones guessed, 0.0460 -> 0.0448 / 0.0802; as a quick search 100% / 98.7%). A thorough search: the padded frame
# is 2.25 times the plain one's, and as a quick search a frame without a face paid 128 ms more for it at 640 x 480
# (dark blurred noise, one core, a busy machine; the quick searches 834 ms there), 80 ms at 1280 x 720 (618 ms).
# Small rolled faces: the turned searches run at the detection width (320 px), where a face about 35 px between
# the eyes in a 960 or 640 px frame is at the cascade's smallest window, and the upright small-face searches
# miss a face rolled 25 degrees: a far speaker under a tilted camera was not found until it happened to be
# upright or larger. The thorough searches turn the frame by each of ``rolled`` at twice the detection width
# after local equalisation, as the small-face searches do (on the clip below, the first 14 frames: plain
# equalisation found the face in none, clipped and local in all; on a dark room at 1280x720 the two searches
# cost 245 ms clipped, 41 local). Measured 2026-11-30 (shipped 3D model): the sample clip shrunk to 0.55 (33 px
# between the eyes), rolled 25 degrees, dim and noisy in a 960x540 frame, tracked as ``aamtrack run`` tracks:
# the first detection at frame 12 -> 0 (278 -> 290 of 302 frames tracked; the other 12 are a faceless gap);
# ``benchmarks/hard_clips.py`` hard2 (34 px, rolled up to 25 degrees, dim) 199 -> 203 of 300 (NME 0.0377 ->
# 0.0380), the other clips the same, rooms 0 tracked either way; ``benchmarks/robustness.py`` stills small30
# 97.6% -> 97.9% within NME 0.08, rot+30 97.0% -> 97.6%, rot-30, small30_hd and dim_small the same, the 21 video
# rows identical. Cost, on a frame
# without a face only, thorough searches (every ``TrackerConfig.thorough_every`` lost frames): about 40 ms on a
# dark room at 1280x720, 270-290 ms on one at 640x480, 320-370 ms on blurred noise at either size (the thorough
# searches took 1.0-2.9 s there before; one core): CLAHE on a noisy frame gives the cascade much to look at.
CLOSE_PAD = 0.25  # share of the frame's shorter side added on every side (edges replicated)
CLOSE_MIN = 0.45  # ... searched for boxes at least this share of that side: close-ups only, few scales
SMALLEST_WIDTHS = (2, 4, 6)  # multiples of DETECT_WIDTH
SMALLEST_BOX = 20  # pixels of the searched image: the smallest box of every search (the cascades' windows are 20-24)


def smallest_widths(frame_width: int) -> list:
    """The widths of the smallest-face searches for a frame this wide: each multiple of ``SMALLEST_WIDTHS``
    times ``DETECT_WIDTH`` that the frame reaches, and the frame's own width when it lies between two."""
    widths = []
    for k in SMALLEST_WIDTHS:
        width = min(k * DETECT_WIDTH, frame_width)
        if not widths or width > widths[-1]:  # capped at the frame's width: once reached, no wider search
            widths.append(width)
    return widths


def overlap(a, b) -> float:
    """Intersection over union of two (x, y, w, h) boxes."""
    x0, y0 = max(a[0], b[0]), max(a[1], b[1])
    x1, y1 = min(a[0] + a[2], b[0] + b[2]), min(a[1] + a[3], b[1] + b[3])
    inter = max(0.0, x1 - x0) * max(0.0, y1 - y0)
    union = a[2] * a[3] + b[2] * b[3] - inter
    return float(inter / union) if union > 0 else 0.0


def equalize_clipped(gray: np.ndarray, clip: float = EQUALIZE_CLIP) -> np.ndarray:
    """Histogram equalisation of a uint8 image (H, W) with each grey level's count clipped at ``clip`` times the
    mean count (H W / 256) and the excess dropped, not spread (the same (H, W) uint8). Plain equalisation
    (``cv2.equalizeHist``) gives a flat background that fills most of the frame most of the output range;
    clipped, it gets at most ``clip`` / 256 of it, and the rest keeps its contrast. A contrast-limited global
    equalisation, as CLAHE limits each tile's (Zuiderveld, Graphics Gems IV, 1994), without its redistribution
    (which adds back a ramp over all levels)."""
    hist = np.bincount(gray.ravel(), minlength=256).astype(np.float64)
    np.minimum(hist, clip * gray.size / 256.0, out=hist)
    cdf = np.cumsum(hist)
    lo = cdf[np.flatnonzero(hist)[0]] if cdf[-1] > 0 else 0.0  # the darkest level present maps to 0
    span = cdf[-1] - lo
    if span <= 0:  # one grey level: nothing to stretch
        return gray.copy()
    lut = np.clip(np.rint(255.0 * (cdf - lo) / span), 0, 255).astype(np.uint8)
    return cv2.LUT(gray, lut)


def mirrored(found: tuple, width: int) -> tuple:
    """``HaarDetector.find``'s (box, angle) for the frame flipped left to right (``width`` pixels wide): the box
    mirrored in its (turned) frame, the angle negated (a frame turned by a degrees and then flipped is the flipped
    frame turned by -a, both about the centre)."""
    (x, y, w, h), angle = found
    return np.array([width - x - w, y, w, h], float), -float(angle)


def unturn(points: np.ndarray, angle: float, shape: tuple) -> np.ndarray:
    """(n, 2) points of a frame turned by ``angle`` degrees about its centre (``HaarDetector.detect_all``),
    mapped back to the frame of ``shape`` (H, W[, C])."""
    if not angle:
        return np.asarray(points, float)
    H, W = shape[:2]
    inv = cv2.invertAffineTransform(cv2.getRotationMatrix2D((W / 2, H / 2), angle, 1.0))
    return np.asarray(points, float) @ inv[:, :2].T + inv[:, 2]


def guess_points(box, box_points: np.ndarray) -> np.ndarray:
    """(68, 2) landmarks guessed from a box with the learned mean positions ``box_points`` (box units)."""
    x, y, w, h = box
    return np.column_stack([x + w * box_points[:, 0], y + h * box_points[:, 1]])
