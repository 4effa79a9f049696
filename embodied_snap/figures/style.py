"""The paper's figure style: IEEE column widths, 8 pt type, vector PDF plus a PNG for reports."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

TEXT_WIDTH_IN = 7.16  # IEEE two-column \textwidth
COLUMN_WIDTH_IN = 3.5
PALETTE = ["#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#F0E442", "#000000"]


def setup() -> None:
    plt.rcParams.update(
        {
            "font.size": 8,
            "axes.titlesize": 8,
            "axes.labelsize": 8,
            "legend.fontsize": 7,
            "xtick.labelsize": 7,
            "ytick.labelsize": 7,
            "axes.spines.top": False,
            "axes.spines.right": False,
            "axes.prop_cycle": matplotlib.cycler(color=PALETTE),
            "pdf.fonttype": 42,  # embed TrueType so the PDF stays editable
            "svg.fonttype": "none",
            "savefig.dpi": 300,
            # Fixed metadata: the same data give the same bytes.
            "pdf.compression": 6,
        }
    )


def panel_label(ax, letter: str) -> None:
    ax.text(-0.12, 1.04, f"({letter})", transform=ax.transAxes, fontweight="bold", va="bottom")


def save(fig, pdf: str, png: str) -> None:
    fig.savefig(pdf, metadata={"CreationDate": None, "ModDate": None, "Producer": None})
    fig.savefig(png, metadata={"Software": None})
    plt.close(fig)
