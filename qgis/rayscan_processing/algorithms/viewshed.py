"""Viewshed from points: `rayscan visibility CLOUD --observers CSV --raster MAP.tif --cell C`."""

from qgis.core import (QgsProcessingParameterDefinition, QgsProcessingParameterEnum,
                       QgsProcessingParameterNumber, QgsProcessingParameterRasterDestination)

from . import observers, styles
from .base import GEOTIFF_EXTENSIONS, PRIMITIVES, RayscanAlgorithm

# `rayscan visibility --raster-value`, in the order the dialog lists them.
_VALUES = ["viewshed", "count", "viewshed-points", "fraction", "distance"]
#: The values whose cells are 1 (seen) or 0, styled as such when loaded.
_SEEN_VALUES = ("viewshed", "viewshed-points")


class Viewshed(RayscanAlgorithm):
    """The viewshed of a point layer of observers over the cloud, as a GeoTIFF."""

    NAME = "viewshed"
    DISPLAY = "Viewshed from points"
    HELP = ("The GIS viewshed of the observers over the cloud (rayscan visibility --raster): rayscan "
            "makes the cloud's DSM (as Ortho + DSM does at this cell size) and casts an exact line of "
            "sight from each eye to every cell centre. Values: viewshed = 1 where some observer sees "
            "the cell, 0 where none does; count = observers that see a point of the cell; "
            "viewshed-points = 1 where some point of the cell is seen (line of sight over the points); "
            "fraction = share of the cell's points seen; distance = nearest observer that sees the "
            "cell. Geometry of each point (advanced): the line of sight over the points (every value but "
            "viewshed, which sees over the DSM) meets surfels, the surface a DSM records, or spheres, "
            "the true 3-D answer that sees under tree crowns. NoData -9999 where the cell has no "
            "surface. The observers are reprojected to the "
            "cloud's CRS; heights and cell size are in the cloud's units (autzen: international feet). "
            "The raster carries the cloud's CRS.")
    OUTPUT = "OUTPUT"
    FLAGS = {**observers.FLAGS, "OUTPUT": "--raster", "CELL": "--cell", "VALUE": "--raster-value",
             "PRIMITIVE": "--primitive", "MAX_DISTANCE": "--max-distance"}

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS's name)
        """Declare the parameters."""
        self.add_cloud_parameter()
        observers.add_observer_parameters(self)
        self.add_cell_parameter()
        self.addParameter(QgsProcessingParameterEnum(
            "VALUE", self.tr("Cell value"), _VALUES, defaultValue=0))
        self.add_primitive_parameter("Geometry of each point", "surfel", advanced=True)
        max_distance = QgsProcessingParameterNumber(
            "MAX_DISTANCE", self.tr("Maximum viewing distance (cloud units; 0 = unlimited)"),
            QgsProcessingParameterNumber.Double, 0.0, minValue=0.0)
        max_distance.setFlags(max_distance.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
        self.addParameter(max_distance)
        self.addParameter(QgsProcessingParameterRasterDestination(self.OUTPUT, self.tr("Viewshed")))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 (QGIS's name)
        """Write the observers, run rayscan visibility and return the raster."""
        cloud = self.cloud(parameters, context)
        out = self.parameterAsOutputLayer(parameters, self.OUTPUT, context)
        self.check_extension(out, GEOTIFF_EXTENSIONS, "The viewshed")
        value = _VALUES[self.parameterAsEnum(parameters, "VALUE", context)]
        observer_file = observers.write_observers(self, parameters, context, feedback, cloud)
        args = (["visibility", cloud] + observers.observer_args(self, parameters, context, observer_file)
                + self.option("OUTPUT", out)
                + ["--no-preview"] + self.option("CELL", self.parameterAsDouble(parameters, "CELL", context))
                + self.option("VALUE", value)
                + self.option("PRIMITIVE", PRIMITIVES[self.parameterAsEnum(parameters, "PRIMITIVE", context)]))
        max_distance = self.parameterAsDouble(parameters, "MAX_DISTANCE", context)
        if max_distance > 0:
            args += self.option("MAX_DISTANCE", max_distance)
        try:
            self.run_cli(args, feedback, rewrite=observer_file.user_terms)
        finally:
            observer_file.remove()
        if value in _SEEN_VALUES:
            styles.style_on_completion(out, styles.SEEN, context)
        return {self.OUTPUT: out}
