"""Ortho + DSM: `rayscan render CLOUD --ortho-map CELL --ortho-colour COLOUR --dsm DSM --out ORTHO`."""

from qgis.core import QgsProcessingParameterEnum, QgsProcessingParameterRasterDestination

from .base import GEOTIFF_EXTENSIONS, RayscanAlgorithm

#: The values of `rayscan render --ortho-colour`, in the CLI's order; the first is its default.
COLOURS = ["albedo", "shaded"]


class OrthoDsm(RayscanAlgorithm):
    """A top-down orthophoto (RGBA GeoTIFF) and digital surface model (Float32 GeoTIFF) of a cloud."""

    NAME = "ortho_dsm"
    DISPLAY = "Ortho + DSM"
    HELP = ("Renders the cloud straight down over its XY extent (rayscan render --ortho-map CELL --dsm): "
            "an RGBA orthophoto (alpha the share of the cell's rays that hit a point) and the digital "
            "surface model, the elevation of the first surface each cell's vertical ray meets (NoData where it "
            "misses). Colour 'albedo' (the default) gives each cell the unshaded colour of the points seen from "
            "above, the mean over Samples per pixel stratified rays through the cell (of those that hit; 1 = the "
            "point under the cell centre): the points' RGB as stored (8-bit sRGB), or the elevation ramp for a "
            "cloud without RGB; 'shaded' gives the path-traced render instead (sky light and shading, Samples "
            "per pixel samples per cell). Both GeoTIFFs carry the cloud's CRS; "
            "the cell size is in the cloud's horizontal units. The DSM is the surface the Viewshed "
            "algorithm sees over.")
    ORTHO = "ORTHO"
    DSM = "DSM"
    FLAGS = {"CELL": "--ortho-map", "COLOUR": "--ortho-colour", "SPP": "--spp", "DSM": "--dsm", "ORTHO": "--out,-o"}

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS's name)
        """Declare the parameters."""
        self.add_cloud_parameter()
        self.add_cell_parameter()
        self.addParameter(QgsProcessingParameterEnum("COLOUR", self.tr("Colour"), COLOURS, defaultValue=0))
        self.add_spp_parameter()
        self.addParameter(QgsProcessingParameterRasterDestination(self.ORTHO, self.tr("Orthophoto")))
        self.addParameter(QgsProcessingParameterRasterDestination(self.DSM, self.tr("DSM")))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 (QGIS's name)
        """Run rayscan render in ortho mode and return both rasters."""
        cloud = self.cloud(parameters, context)
        ortho = self.parameterAsOutputLayer(parameters, self.ORTHO, context)
        dsm = self.parameterAsOutputLayer(parameters, self.DSM, context)
        self.check_extension(ortho, GEOTIFF_EXTENSIONS, "The orthophoto")
        self.check_extension(dsm, GEOTIFF_EXTENSIONS, "The DSM")
        self.run_cli(["render", cloud] + self.option("CELL", self.parameterAsDouble(parameters, "CELL", context))
                     + self.option("COLOUR", COLOURS[self.parameterAsEnum(parameters, "COLOUR", context)])
                     + self.option("SPP", self.parameterAsInt(parameters, "SPP", context))
                     + self.option("DSM", dsm) + self.option("ORTHO", ortho), feedback)
        return {self.ORTHO: ortho, self.DSM: dsm}
