"""The rayscan Processing algorithms, one per module."""

from .ortho_dsm import OrthoDsm
from .point_visibility import PointVisibility
from .quick_look import QuickLook
from .solar import Solar
from .viewshed import Viewshed

#: Every algorithm class the provider offers.
ALGORITHMS = [QuickLook, OrthoDsm, Viewshed, PointVisibility, Solar]
