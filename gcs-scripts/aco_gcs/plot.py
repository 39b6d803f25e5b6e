"""PNG and CSV output: matplotlib with the Agg backend (no display needed)."""

import csv
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def figure(rows=1, cols=1, size=(8, 5), **kwargs):
    return plt.subplots(rows, cols, figsize=size, **kwargs)


def save(fig, path):
    """Write `fig` to `path` as PNG (creating the directory) and close it."""
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=110)
    plt.close(fig)
    return path


def write_csv(path, header, rows):
    directory = os.path.dirname(os.path.abspath(path))
    os.makedirs(directory, exist_ok=True)
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(header)
        writer.writerows(rows)
    return path
