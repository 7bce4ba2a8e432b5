"""Draws the figures of docs/concepts/forward-mapping.md.

Run from the repository root with the package installed (``make build``):

    .venv/bin/python docs/concepts/figures/forward_mapping.py

The mesh diagram recomputes the skirt geometry from the rules the page states (so the
page's description is checked to be complete enough to implement); every other picture is
rendered by ``inkwarp.warp_image`` itself.
"""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Polygon  # noqa: E402
from PIL import Image, ImageDraw  # noqa: E402

import inkwarp  # noqa: E402
from inkwarp.imaging import write_png  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))


# ---------------------------------------------------------------- the art


def test_card(size: int = 160) -> np.ndarray:
    """A checkerboard with a disc, a ring and a diagonal band: edges in every direction."""
    image = Image.new("RGBA", (size, size), (0, 0, 0, 0))
    draw = ImageDraw.Draw(image)
    cell = size // 10
    for j in range(10):
        for i in range(10):
            colour = (236, 230, 214, 255) if (i + j) % 2 == 0 else (52, 82, 122, 255)
            draw.rectangle([i * cell, j * cell, (i + 1) * cell - 1, (j + 1) * cell - 1], colour)
    draw.polygon([(0, size * 0.7), (size * 0.3, size), (0, size)], fill=(230, 160, 40, 255))
    c = size / 2
    draw.ellipse([c - 38, c - 38, c + 38, c + 38], fill=(205, 60, 50, 255))
    draw.ellipse([c - 20, c - 20, c + 20, c + 20], fill=(250, 240, 120, 255))
    return np.asarray(image).copy()


def field_from(h: int, w: int, f) -> np.ndarray:
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    dx, dy = f(x, y)
    return np.stack([dx, dy], axis=-1).astype(np.float32)


# ---------------------------------------------------------------- the mesh diagram


def skirt_elements(pos: np.ndarray, right: np.ndarray, down: np.ndarray):
    """Quads and skirt quarters of a small mesh, following the page's rules.

    pos: (H, W, 2) canvas positions; right/down: (H, W) bool links. Yields
    ("quad" | "quarter", corners TL, TR, BR, BL).
    """
    h, w = pos.shape[:2]

    def frame(x, y):
        ex = ey = None
        if right[y, x]:
            ex = pos[y, x + 1] - pos[y, x]
        elif x > 0 and right[y, x - 1]:
            ex = pos[y, x] - pos[y, x - 1]
        if down[y, x]:
            ey = pos[y + 1, x] - pos[y, x]
        elif y > 0 and down[y - 1, x]:
            ey = pos[y, x] - pos[y - 1, x]
        if ex is None and ey is None:
            return np.array([1.0, 0.0]), np.array([0.0, 1.0])
        if ex is None:
            return np.array([ey[1], -ey[0]]), ey
        if ey is None:
            return ex, np.array([-ex[1], ex[0]])
        return ex, ey

    for r in range(-1, h):
        for c in range(-1, w):
            corners = [(c, r), (c + 1, r), (c, r + 1), (c + 1, r + 1)]  # TL TR BL BR
            present = [0 <= x < w and 0 <= y < h for x, y in corners]
            if not any(present):
                continue
            top = present[0] and present[1] and right[r, c]
            bottom = present[2] and present[3] and right[r + 1, c]
            left = present[0] and present[2] and down[r, c]
            rgt = present[1] and present[3] and down[r, c + 1]
            if top and bottom and left and rgt:
                p = [pos[y, x] for x, y in corners]
                yield "quad", [p[0], p[1], p[3], p[2]]
                continue
            links = {(0, 1): top, (2, 3): bottom, (0, 2): left, (1, 3): rgt}

            def linked(a, b):
                return links.get((min(a, b), max(a, b)), False)

            hpt, vpt, completion = {}, {}, {}
            for k in range(4):
                if not present[k]:
                    continue
                x, y = corners[k]
                p = pos[y, x]
                ex, ey = frame(x, y)
                sx = 0.5 if k % 2 == 0 else -0.5
                sy = 0.5 if k < 2 else -0.5
                q = k ^ 1
                hpt[k] = (p + pos[corners[q][1], corners[q][0]]) / 2 if linked(k, q) else p + sx * ex
                q = k ^ 2
                vpt[k] = (p + pos[corners[q][1], corners[q][0]]) / 2 if linked(k, q) else p + sy * ey
                completion[k] = hpt[k] + vpt[k] - p
            for k in range(4):
                if not present[k]:
                    continue
                # The component of k through the block's links.
                comp, grew = {k}, True
                while grew:
                    grew = False
                    for a, b in links:
                        if links[(a, b)] and (a in comp) != (b in comp):
                            comp |= {a, b}
                            grew = True
                centre = np.mean([completion[j] for j in comp], axis=0)
                x, y = corners[k]
                p, hh, vv = pos[y, x], hpt[k], vpt[k]
                order = {0: [p, hh, centre, vv], 1: [hh, p, vv, centre],
                         2: [vv, centre, hh, p], 3: [centre, vv, p, hh]}[k]
                yield "quarter", order


def mesh_figure(path: str) -> None:
    h, w = 4, 6
    right = np.ones((h, w), bool)
    down = np.ones((h, w), bool)
    right[:, -1] = False
    down[-1, :] = False
    right[1:, 2] = False  # a cut between columns 2 and 3, from row 1 down
    y, x = np.mgrid[0:h, 0:w].astype(float)
    rest = np.stack([x, y], -1)
    bend = rest + np.stack([np.where(x >= 3, 0.5 + 0.15 * y, -0.25 * y), 0.12 * (x - 2.5) ** 2 * 0.5], -1)
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    for ax, pos, title in ((axes[0], rest, "at rest (identity field)"), (axes[1], bend, "displaced: the cut opens")):
        for kind, q in skirt_elements(pos, right, down):
            face = "#9ecae1" if kind == "quad" else "#fdd0a2"
            ax.add_patch(Polygon(np.array(q), closed=True, facecolor=face, edgecolor="#636363",
                                 linewidth=0.6, linestyle="-" if kind == "quad" else "--"))
        ax.plot(pos[..., 0].ravel(), pos[..., 1].ravel(), "o", color="#08306b", markersize=4)
        for yy in range(h):
            for xx in range(w - 1):
                if right[yy, xx]:
                    ax.plot(*np.array([pos[yy, xx], pos[yy, xx + 1]]).T, color="#08306b", linewidth=1)
        for yy in range(h - 1):
            for xx in range(w):
                if down[yy, xx]:
                    ax.plot(*np.array([pos[yy, xx], pos[yy + 1, xx]]).T, color="#08306b", linewidth=1)
        ax.set_title(title)
        ax.set_aspect("equal")
        ax.invert_yaxis()
        ax.set_xlim(pos[..., 0].min() - 0.9, pos[..., 0].max() + 0.9)
        ax.set_ylim(pos[..., 1].max() + 0.9, pos[..., 1].min() - 0.9)
        ax.set_xticks(range(w))
        ax.set_yticks(range(h))
        ax.grid(True, color="#eeeeee", linewidth=0.5)
    fig.text(0.5, 0.01, "dots: pixels (mesh vertices)    lines: links    blue: quads    "
             "orange, dashed: skirt quarters    (a cut between columns 2 and 3, from row 1 down)",
             ha="center", fontsize=9)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---------------------------------------------------------------- rendered figures


def zoom(image: np.ndarray, factor: int) -> np.ndarray:
    """Nearest-neighbour enlargement over a light checker, to show alpha."""
    h, w = image.shape[:2]
    checker = ((np.indices((h * factor, w * factor)) // (factor * 2)).sum(0) % 2) * 40 + 200
    big = image.repeat(factor, 0).repeat(factor, 1).astype(float)
    a = big[..., 3:4] / 255.0
    rgb = big[..., :3] * a + checker[..., None] * (1 - a)
    return np.concatenate([rgb, np.full(rgb.shape[:2] + (1,), 255.0)], -1).astype(np.uint8)


def over_checker(image: np.ndarray) -> np.ndarray:
    return zoom(image, 1)


def warps_figure(path: str) -> None:
    card = test_card()
    h, w = card.shape[:2]
    c = (w - 1) / 2

    def rotation(x, y, angle=0.35, scale=0.8):
        u, v = x - c, y - c
        co, si = np.cos(angle), np.sin(angle)
        return scale * (co * u - si * v) - u, scale * (si * u + co * v) - v

    sine = field_from(h, w, lambda x, y: (7 * np.sin(y / 14.0), 7 * np.sin(x / 17.0)))
    # A slit in the matte along the middle column's upper part, pulled apart.
    matte = card[..., 3] > 0
    slit = card.copy()
    slit[10:90, 79:81] = 0
    matte_slit = matte.copy()
    matte_slit[10:90, 79:81] = False
    pull = field_from(h, w, lambda x, y: (np.where(x < 80, -1.0, 1.0) * 9 * np.clip((95 - y) / 85, 0, 1), 0 * x))
    # Fold-over: the right half slides over the left.
    fold = field_from(h, w, lambda x, y: (np.where(x >= 80, -40.0 * np.clip((y - 20) / 60, 0, 1), 0.0), 0 * x))
    panels = [
        ("the layer", card),
        ("rotation + scale", inkwarp.warp_image(card, field_from(h, w, rotation))),
        ("sine warp: no cracks", inkwarp.warp_image(card, sine)),
        ("a slit in the matte, pulled open", inkwarp.warp_image(slit, pull, matte_slit)),
        ("the same field, no slit", inkwarp.warp_image(card, pull)),
        ("fold-over: later rows/columns in front", inkwarp.warp_image(card, fold)),
    ]
    fig, axes = plt.subplots(2, 3, figsize=(10.5, 7.4))
    for ax, (title, image) in zip(axes.ravel(), panels):
        ax.imshow(over_checker(image), interpolation="nearest")
        ax.set_title(title, fontsize=10)
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def edges_figure(path: str) -> None:
    """A sub-pixel translation: analytic coverage vs point sampling of the same mesh."""
    card = test_card()[60:84, 36:60]
    h, w = card.shape[:2]
    pad = np.zeros((h + 4, w + 4, 4), np.uint8)
    pad[2:-2, 2:-2] = card
    t = (0.4, 0.3)
    moved = inkwarp.warp_image(pad, np.broadcast_to(np.float32(t), pad.shape[:2] + (2,)).copy())
    # Point sampling: each output pixel takes the nearest rest pixel (what a renderer
    # without coverage would do for a translation).
    yy, xx = np.mgrid[0 : h + 4, 0 : w + 4]
    sx = np.clip(np.round(xx - t[0]).astype(int), 0, w + 3)
    sy = np.clip(np.round(yy - t[1]).astype(int), 0, h + 3)
    nearest = pad[sy, sx]
    fig, axes = plt.subplots(1, 3, figsize=(10, 3.8))
    for ax, (title, image) in zip(axes, [("rest", pad), ("moved by (0.4, 0.3): coverage", moved),
                                         ("nearest pixel (no antialiasing)", nearest)]):
        ax.imshow(zoom(image, 8), interpolation="nearest")
        ax.set_title(title, fontsize=10)
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main() -> None:
    mesh_figure(os.path.join(HERE, "forward-mapping-mesh.png"))
    warps_figure(os.path.join(HERE, "forward-mapping-warps.png"))
    edges_figure(os.path.join(HERE, "forward-mapping-edges.png"))
    write_png(os.path.join(HERE, "forward-mapping-card.png"), test_card())
    for name in sorted(os.listdir(HERE)):
        if name.endswith(".png"):
            print(os.path.join(HERE, name))


if __name__ == "__main__":
    main()
