"""Facts about this machine and its processes, from ``/proc`` (no psutil)."""
from __future__ import annotations

import os
import platform
from pathlib import Path
from typing import Any

import numpy as np

CLK_TCK = os.sysconf('SC_CLK_TCK')


def machine_info() -> dict[str, Any]:
    """CPU model, core count, Python and numpy versions."""
    model = platform.processor() or 'unknown'
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                model = line.split(':', 1)[1].strip()
                break
    except OSError:
        pass
    return {'cpu_model': model, 'cores': os.cpu_count(), 'python': platform.python_version(),
            'numpy': np.__version__, 'platform': platform.platform(),
            'loadavg_1min': os.getloadavg()[0]}


def proc_cpu_s(pid: int) -> float:
    """utime + stime of a process, s (from /proc/<pid>/stat)."""
    text = Path(f'/proc/{pid}/stat').read_text()
    fields = text[text.rindex(')') + 2:].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK  # fields 14, 15 of stat(5)


def proc_rss_mb(pid: int | str = 'self', key: str = 'VmRSS') -> float:
    """VmRSS (or VmHWM, ...) of a process, MiB."""
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith(key + ':'):
            return int(line.split()[1]) / 1024.0
    return float('nan')
