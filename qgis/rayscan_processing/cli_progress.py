"""Reading rayscan's progress lines (standard error into a pipe); no QGIS import, so it is testable alone."""

import re

# Into a pipe rayscan writes plain lines, never a carriage return (base/src/progress.cpp and
# tools/phase_progress.hpp):
#   "progress: 12/215 chunks   5.6%  341999 points/s  ETA 3 s"   (render, visibility, solar)
#   "index: sort  42.0%  4200000 / 10000000 points  3.1 M points/s"  (phased jobs)
# The percentage is the number glued to "%"; log lines such as "(26.5 %)" put a space before it.
_PROGRESS = re.compile(r"^progress: \d+/\d+ \S+\s+(\d+(?:\.\d+)?)%")
_PHASE = re.compile(r"^[a-z]+(?: [a-z]+)?: [a-z][\w -]*?\s+(\d+(?:\.\d+)?)%\s")


def parse_progress(line):
    """Return the percentage (0..100) a rayscan progress line reports, or None for any other line."""
    m = _PROGRESS.match(line) or _PHASE.match(line)
    if not m:
        return None
    return max(0.0, min(100.0, float(m.group(1))))
