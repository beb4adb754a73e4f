"""stderr as the command-line tests count it.

``aamtrack run`` says it is compiling the kernels when their warm-up takes over 1.5 s (``commands.run._warm_up``):
a fresh install's first run in a test process, or a busy machine. Tests that count the lines about their own
case leave those two notices out.
"""

from __future__ import annotations

KERNEL_NOTICES = ("compiling kernels", "kernels ready")


def stderr_lines(capsys) -> list[str]:
    """capsys's stderr so far, as lines, without the kernels' notices."""
    return [line for line in capsys.readouterr().err.strip().splitlines() if not line.startswith(KERNEL_NOTICES)]
