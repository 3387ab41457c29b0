"""Quick look: `rayscan render CLOUD --out IMAGE`, a path-traced overview of the cloud."""

from qgis.core import QgsProcessingParameterFileDestination, QgsProcessingParameterNumber, QgsProcessingUtils

from .base import IMAGE_EXTENSIONS, IMAGE_FILTER, PRIMITIVES, RayscanAlgorithm


class QuickLook(RayscanAlgorithm):
    """Render an overview image of a point cloud (perspective, automatic camera)."""

    NAME = "quick_look"
    DISPLAY = "Quick look render"
    HELP = ("Path-traces the point cloud from an automatic overview camera framing the whole cloud "
            "(rayscan render CLOUD): colour from the points' RGB, else elevation; the default sky gradient, no sun. "
            "The image is a perspective view, so it has no map coordinates: it loads as a picture "
            "without a CRS. For a map use Ortho + DSM.")
    OUTPUT = "OUTPUT"
    FLAGS = {"WIDTH": "--width", "SPP": "--spp", "PRIMITIVE": "--primitive", "OUTPUT": "--out,-o"}

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS's name)
        """Declare the parameters."""
        self.add_cloud_parameter()
        self.addParameter(QgsProcessingParameterNumber(
            "WIDTH", self.tr("Image width (pixels; the height follows the camera's aspect ratio)"),
            QgsProcessingParameterNumber.Integer, 1024, minValue=1, maxValue=65536))
        self.add_spp_parameter()
        self.add_primitive_parameter("Geometry of each point", "surfel")
        self.addParameter(QgsProcessingParameterFileDestination(
            self.OUTPUT, self.tr("Quick look image"), IMAGE_FILTER))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 (QGIS's name)
        """Run rayscan render and return the image's path."""
        cloud = self.cloud(parameters, context)
        out = self.parameterAsFileOutput(parameters, self.OUTPUT, context)
        self.check_extension(out, IMAGE_EXTENSIONS, "The quick look")
        self.run_cli(["render", cloud] + self.option("OUTPUT", out)
                     + self.option("WIDTH", self.parameterAsInt(parameters, "WIDTH", context))
                     + self.option("SPP", self.parameterAsInt(parameters, "SPP", context))
                     + self.option("PRIMITIVE", PRIMITIVES[self.parameterAsEnum(parameters, "PRIMITIVE", context)]),
                     feedback)
        self.load_on_completion(out, self.tr("Quick look"), self.OUTPUT, context,
                                QgsProcessingUtils.LayerHint.Raster)
        return {self.OUTPUT: out}
