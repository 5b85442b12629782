"""3-D pictures of bodies for the report, drawn offline with matplotlib (no display, no GPU).

A picture is a list of :class:`MeshItem` (a triangle mesh in world coordinates with a colour per
face) and of :class:`Segment` (witness segments, penetration vectors), seen from one camera. Faces
are shaded by a light fixed to the camera (ambient + Lambert), faces turned away from the camera
are dropped (the bodies are closed and convex: they cannot be seen), and everything goes into one
Poly3DCollection, so matplotlib sorts all bodies' faces by depth together. Segments are drawn
last, on top of the bodies, so that a witness segment between two bodies stays visible.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from harness.report.charts import pyplot

# colours of the bounding volumes and of the STP-BV patch kinds (RGB in [0, 1])
COLOURS = {
    "pch": (0.35, 0.50, 0.72),          # polyhedral hull: steel blue
    "cse": (0.36, 0.66, 0.42),          # superellipsoid: green
    "small_sphere": (0.90, 0.45, 0.15),  # STP-BV vertex patches (radius r): orange
    "big_sphere": (0.96, 0.80, 0.35),    # STP-BV face patches (radius R): light gold
    "torus": (0.55, 0.35, 0.70),         # STP-BV edge patches: purple
}
STP_KIND_INDEX = {"small_sphere": 0, "big_sphere": 1, "torus": 2}
AMBIENT = 0.45  # share of a face's colour lit whatever its normal
KEY_LIGHT = (25.0, -30.0)  # degrees (elevation, azimuth) of the key light from the camera direction
FILL_LIGHT = (-10.0, 60.0)  # ... and of a weaker fill light from the other side
FILL = 0.25  # the fill light's strength against the key light's
BOX_ZOOM = 1.3  # matplotlib draws a 3-D box well inside its axes; this fills them


@dataclass
class MeshItem:
    """A mesh placed in the world: vertices (n, 3) world frame (m), faces (m, 3), face colours (m, 3)
    RGB in [0, 1] (or one (3,) colour), alpha in (0, 1]; ``edges``: draw face edges (thin lines)."""

    vertices: np.ndarray
    faces: np.ndarray
    colours: np.ndarray
    alpha: float = 1.0
    edges: bool = False

    @classmethod
    def of(cls, mesh, pose=None, colour=None, alpha: float = 1.0, edges: bool = False) -> "MeshItem":
        """From a trimesh mesh in its local frame, a 4x4 pose (local -> world) and one colour; an
        STP-BV mesh without a colour is coloured by patch kind (mesh.metadata['face_kind'])."""
        v = np.asarray(mesh.vertices, dtype=np.float64)
        if pose is not None:
            pose = np.asarray(pose, dtype=np.float64)
            v = v @ pose[:3, :3].T + pose[:3, 3]
        faces = np.asarray(mesh.faces)
        if colour is None and "face_kind" in mesh.metadata:
            colours = np.array([COLOURS[k] for k in mesh.metadata["face_kind"]])
        else:
            colours = np.tile(np.asarray(colour if colour is not None else COLOURS["pch"], dtype=float), (len(faces), 1))
        return cls(v, faces, colours, alpha, edges)


@dataclass
class Segment:
    """A segment from ``start`` to ``end`` (world, m), drawn with its end points; ``arrow``: an arrow
    head at ``end``; ``label`` written beside its middle."""

    start: np.ndarray
    end: np.ndarray
    colour: str = "black"
    width: float = 2.0
    arrow: bool = False
    label: str = ""


@dataclass
class View:
    """Camera: elevation and azimuth (degrees, matplotlib's convention), and the world box shown
    (centre (3,), half-widths (3,) or one for all axes, m; equal scales on the three axes)."""

    elev: float = 20.0
    azim: float = -60.0
    centre: np.ndarray = field(default_factory=lambda: np.zeros(3))
    half_width: object = 0.2


def camera_direction(elev: float, azim: float) -> np.ndarray:
    """Unit vector from the scene towards matplotlib's camera at (elev, azim) degrees."""
    e, a = np.radians(elev), np.radians(azim)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


def fit_view(points: np.ndarray, elev: float = 20.0, azim: float = -60.0, margin: float = 1.05) -> View:
    """A view of the axis-aligned box around (n, 3) points (m); no side under a third of the longest."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    half = 0.5 * margin * (hi - lo)
    return View(elev, azim, 0.5 * (lo + hi), np.maximum(half, half.max() / 3.0))


def shade(colours: np.ndarray, normals: np.ndarray, key: np.ndarray, fill: np.ndarray) -> np.ndarray:
    """Face colours (m, 3) lit by a key and a fill light (unit vectors): ambient + Lambert."""
    lambert = np.clip(normals @ key, 0.0, 1.0) + FILL * np.clip(normals @ fill, 0.0, 1.0)
    return np.clip(colours * (AMBIENT + (1.0 - AMBIENT) * lambert)[:, None], 0.0, 1.0)


def draw(ax, items: list[MeshItem], segments: list[Segment], view: View) -> None:
    """Draw the meshes and segments into a 3-D axes, seen from ``view``; hides the axes."""
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    eye = camera_direction(view.elev, view.azim)
    key = camera_direction(view.elev + KEY_LIGHT[0], view.azim + KEY_LIGHT[1])
    fill = camera_direction(view.elev + FILL_LIGHT[0], view.azim + FILL_LIGHT[1])
    polys, face_colours, edge_colours = [], [], []
    for item in items:
        tri = item.vertices[item.faces]  # (m, 3, 3)
        normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        length = np.linalg.norm(normals, axis=1)
        normals = normals / np.where(length > 0, length, 1.0)[:, None]
        keep = (normals @ eye > 0.0) if item.alpha >= 1.0 else np.ones(len(tri), dtype=bool)
        rgb = shade(item.colours[keep], normals[keep], key, fill)
        rgba = np.column_stack([rgb, np.full(len(rgb), item.alpha)])
        polys.append(tri[keep])
        face_colours.append(rgba)
        edge = np.column_stack([0.6 * rgb, np.full(len(rgb), 0.5 * item.alpha)]) if item.edges else rgba
        edge_colours.append(edge)
    if polys:
        collection = Poly3DCollection(np.concatenate(polys), facecolors=np.concatenate(face_colours),
                                      edgecolors=np.concatenate(edge_colours), linewidths=0.15)
        ax.add_collection3d(collection)
    for s in segments:
        (x0, y0, z0), (x1, y1, z1) = s.start, s.end
        ax.plot([x0, x1], [y0, y1], [z0, z1], color=s.colour, linewidth=s.width, zorder=10)
        ax.scatter([x0, x1], [y0, y1], [z0, z1], color=s.colour, s=10, depthshade=False, zorder=11)
        if s.arrow:
            d = np.asarray(s.end) - np.asarray(s.start)
            ax.quiver(x0, y0, z0, *d, color=s.colour, linewidth=s.width, arrow_length_ratio=0.25, zorder=12)
        if s.label:
            mid = 0.5 * (np.asarray(s.start) + np.asarray(s.end))
            ax.text(*mid, "  " + s.label, color=s.colour, fontsize=8, zorder=13)
    half = np.broadcast_to(np.asarray(view.half_width, dtype=float), (3,))
    for setter, c, h in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), view.centre, half):
        setter(c - h, c + h)
    ax.set_box_aspect(tuple(half / half.max()), zoom=BOX_ZOOM)
    ax.view_init(elev=view.elev, azim=view.azim)
    ax.set_axis_off()
    ax.computed_zorder = False  # segments (zorder 10+) over the bodies


def figure(columns: int, size: float = 3.6, height: float | None = None, widths=None):
    """A figure of one row of ``columns`` 3-D axes, each about ``size`` inches wide (``widths``:
    relative widths) and ``height`` inches high (default: ``size``); returns (fig, axes list)."""
    plt = pyplot()
    widths = list(widths) if widths is not None else [1.0] * columns
    fig = plt.figure(figsize=(size * sum(widths), height or size))
    grid = fig.add_gridspec(1, columns, width_ratios=widths)
    axes = [fig.add_subplot(grid[0, k], projection="3d") for k in range(columns)]
    return fig, axes


def legend(fig, entries: list[tuple[str, tuple]], **kwargs) -> None:
    """A figure legend of coloured squares: entries (label, RGB)."""
    from matplotlib.patches import Patch

    fig.legend(handles=[Patch(facecolor=c, edgecolor="0.4", label=label) for label, c in entries],
               loc=kwargs.pop("loc", "lower center"), ncol=kwargs.pop("ncol", len(entries)), frameon=False,
               fontsize=kwargs.pop("fontsize", 9), **kwargs)
