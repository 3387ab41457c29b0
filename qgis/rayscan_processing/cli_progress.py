"""Reading rayscan's progress lines (standard error into a pipe); no QGIS import, so it is testable alone."""

import re

# Into a pipe rayscan writes plain lines, never a carriage return (base/src/progress.cpp and
# tools/phase_progress.hpp):
#   "progress: 12/215 chunks   5.6%  341999 points/s  ETA 3 s"   (render, visibility, solar, query)
#   "progress: 110000/110000 points (surfels) 100.0%  622378 points/s  done in 0 s"
#   "index: sort  42.0%  4200000 / 10000000 points  3.1 M points/s"  (phased jobs)
# After "progress: DONE/TOTAL" comes the name of the items counted (ProgressUnits::item), which may
# be several words ("points (surfels)", "ray blocks"); the percentage is the first number glued to
# "%" after it. Log lines such as "(26.5 %)" put a space before the "%".
_PROGRESS = re.compile(r"^progress: \d+/\d+ \S.*?\s(\d+(?:\.\d+)?)%(?:\s|$)")
_PHASE = re.compile(r"^[a-z]+(?: [a-z]+)?: [a-z][\w -]*?\s+(\d+(?:\.\d+)?)%\s")


def parse_progress(line):
    """Return the percentage (0..100) a rayscan progress line reports, or None for any other line."""
    m = _PROGRESS.match(line) or _PHASE.match(line)
    if not m:
        return None
    return max(0.0, min(100.0, float(m.group(1))))
