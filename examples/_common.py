"""What the examples share: where they write their figures and files, and the example-robot-data URDFs they load.

Not an example itself: each example imports it from beside it (``python examples/<name>.py`` puts
``examples/`` on the import path).
"""

from __future__ import annotations

import importlib.metadata
import os
from pathlib import Path


def output_dir(out_dir=None) -> Path:
    """``out_dir``, else ``$JAXSKID_EXAMPLE_OUT``, else ``examples/out/``; created if missing."""
    path = Path(out_dir or os.environ.get("JAXSKID_EXAMPLE_OUT") or Path(__file__).parent / "out")
    path.mkdir(parents=True, exist_ok=True)
    return path


def erd_urdf(path: str) -> Path:
    """A URDF of the example-robot-data package, by its path under the package's ``robots/`` folder."""
    share = importlib.metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data")
    return Path(share) / "robots" / path


def save_figure(fig, path: Path, dpi: int = 100) -> Path:
    """Lay ``fig`` out, write it to ``path`` and close it; returns ``path``."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path
