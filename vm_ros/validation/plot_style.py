"""What every validation figure shares: the title with the check's status and the paper's claim
(matplotlib, Agg backend; imported only when plotting)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from vm_ros.validation.results import CheckResult  # noqa: E402


def finish(fig, result: CheckResult, path: Path, top: float = 0.9) -> None:
    status = result.status
    # about 13 characters of 9 pt text per inch of figure width
    claim = textwrap.fill(f"Paper: {result.claim}", int(13 * fig.get_figwidth()))
    fig.suptitle(f"{result.title}  [{status}]\n{claim}", fontsize=9)
    fig.tight_layout(rect=(0, 0, 1, top))
    fig.savefig(path, dpi=100)
    plt.close(fig)
