"""Per-point visibility: `rayscan visibility CLOUD --observers CSV -o OUT.las`."""

from qgis.core import (QgsProcessing, QgsProcessingParameterBoolean, QgsProcessingParameterDefinition,
                       QgsProcessingParameterFeatureSink, QgsProcessingParameterFileDestination,
                       QgsProcessingParameterNumber)

from . import observers
from .base import POINTS_EXTENSIONS, POINTS_FILTER, PRIMITIVES, RayscanAlgorithm


class PointVisibility(RayscanAlgorithm):
    """Every point of the cloud with the number of observers that see it (field visible_count)."""

    NAME = "point_visibility"
    DISPLAY = "Per-point visibility"
    HELP = ("Writes the cloud with the field visible_count (observers that see the point) and, when "
            "asked, visible_distance (nearest observer that sees it, -1 none), as LAS extra bytes "
            "(rayscan visibility -o). Line of sight over the points themselves: surfel reads them as "
            "the surface a DSM records; sphere is the true 3-D answer that sees under tree crowns. "
            "A LAS/LAZ output loads as a point cloud layer where QGIS has the PDAL provider (Debian's "
            "QGIS 3.22 has none); the optional point vector layer holds every point with its fields "
            "(fine for thousands to a few million points).")
    OUTPUT = "OUTPUT"
    POINTS_LAYER = "POINTS_LAYER"
    FLAGS = {**observers.FLAGS, "OUTPUT": "-o,--out", "PRIMITIVE": "--primitive",
             "DISTANCE": "--distance", "MAX_DISTANCE": "--max-distance"}

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS's name)
        """Declare the parameters."""
        self.add_cloud_parameter()
        observers.add_observer_parameters(self)
        self.add_primitive_parameter("Geometry of each point", "surfel")
        self.addParameter(QgsProcessingParameterBoolean(
            "DISTANCE", self.tr("Add the field visible_distance"), defaultValue=False))
        max_distance = QgsProcessingParameterNumber(
            "MAX_DISTANCE", self.tr("Maximum viewing distance (cloud units; 0 = unlimited)"),
            QgsProcessingParameterNumber.Double, 0.0, minValue=0.0)
        max_distance.setFlags(max_distance.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
        self.addParameter(max_distance)
        self.addParameter(QgsProcessingParameterFileDestination(
            self.OUTPUT, self.tr("Cloud with visibility fields"), POINTS_FILTER))
        self.addParameter(QgsProcessingParameterFeatureSink(
            self.POINTS_LAYER, self.tr("Points with visibility fields (vector layer)"),
            QgsProcessing.TypeVectorPoint, optional=True, createByDefault=False))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 (QGIS's name)
        """Write the observers, run rayscan visibility -o and return the cloud."""
        cloud = self.cloud(parameters, context)
        out = self.parameterAsFileOutput(parameters, self.OUTPUT, context)
        self.check_extension(out, POINTS_EXTENSIONS, "The output cloud")
        # Decided before rayscan runs: a layer left empty ("") is not asked for.
        points_layer = self.sink_requested(parameters, self.POINTS_LAYER, context)
        observer_file = observers.write_observers(self, parameters, context, feedback, cloud)
        args = (["visibility", cloud] + observers.observer_args(self, parameters, context, observer_file)
                + self.option("OUTPUT", out)
                + self.option("PRIMITIVE", PRIMITIVES[self.parameterAsEnum(parameters, "PRIMITIVE", context)]))
        if self.parameterAsBool(parameters, "DISTANCE", context):
            args.append(self.flag("DISTANCE"))
        max_distance = self.parameterAsDouble(parameters, "MAX_DISTANCE", context)
        if max_distance > 0:
            args += self.option("MAX_DISTANCE", max_distance)
        try:
            self.run_cli(args, feedback, rewrite=observer_file.user_terms)
        finally:
            observer_file.remove()
        results = {self.OUTPUT: out}
        self.load_cloud_on_completion(out, self.tr("Per-point visibility"), self.OUTPUT, context, feedback)
        if points_layer:
            # The observers' CRS (the one QGIS reads from rayscan's rasters), so the layer lies
            # exactly on a viewshed of the same cloud in any project CRS.
            results[self.POINTS_LAYER] = self.cloud_to_sink(out, parameters, self.POINTS_LAYER, observer_file.crs,
                                                            context, feedback)
        return results
