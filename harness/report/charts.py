"""What every chart of the report shares: a headless backend and how a figure is saved."""

from __future__ import annotations


def pyplot():
    """matplotlib.pyplot on the Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path, title: str = "") -> None:
    """Give the figure its overall title (if any), lay it out, write it as PNG (120 dpi), close it."""
    plt = pyplot()
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def failure_heatmap(bad, judged, path, title: str, label: str, floor: float = -4.0, line_after: int = 0) -> None:
    """Rows x columns (two aligned DataFrames of counts: bad, judged), colour: log10 share bad, none
    white, nothing judged grey ('n/a'); each cell's bad/judged written in it; a line under the first
    ``line_after`` rows (0: none). Saved as a PNG at path."""
    import numpy as np

    plt = pyplot()
    rows, cols = list(bad.index), list(bad.columns)
    share = (bad / judged).to_numpy(dtype=float)
    shown = np.where(share > 0, np.log10(np.maximum(share, 10 ** floor)), np.nan)
    shown = np.where(np.isfinite(share) & (share == 0), floor - 1, shown)
    fig, ax = plt.subplots(figsize=(1.25 * len(cols) + 3.5, 0.32 * len(rows) + 2.2))
    cmap = plt.get_cmap("Reds").with_extremes(under="white", bad="#e8e8e8")
    im = ax.imshow(np.ma.masked_invalid(shown), cmap=cmap, vmin=floor, vmax=0.0, aspect="auto")
    ax.set_xticks(range(len(cols)), cols, rotation=20, ha="right")
    ax.set_yticks(range(len(rows)), rows, fontsize=8)
    for i in range(len(rows)):
        for j in range(len(cols)):
            q = judged.iat[i, j]
            if np.isfinite(q) and q > 0:
                dark = np.isfinite(shown[i, j]) and shown[i, j] > floor / 2.7
                ax.text(j, i, f"{int(bad.iat[i, j])}/{int(q)}", ha="center", va="center", fontsize=6.5,
                        color="white" if dark else "black")
            else:
                ax.text(j, i, "n/a", ha="center", va="center", fontsize=6.5, color="grey")
    if 0 < line_after < len(rows):
        ax.axhline(line_after - 0.5, color="black", lw=1.2)
    fig.colorbar(im, ax=ax, label=label, extend="min")
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
