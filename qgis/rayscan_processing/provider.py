"""The ``rayscan`` Processing provider: the algorithms and the executable option."""

from qgis.core import QgsApplication, QgsProcessingProvider

from . import runner
from .algorithms import ALGORITHMS

try:  # The Processing plugin's options page; absent where only qgis.core is loaded.
    from processing.core.ProcessingConfig import ProcessingConfig, Setting
except ImportError:  # pragma: no cover
    ProcessingConfig = None


class RayscanProvider(QgsProcessingProvider):
    """Processing provider ``rayscan``: ray-query analyses of raw point clouds through the rayscan CLI."""

    def id(self):
        """The prefix of the algorithm ids (``rayscan:viewshed``)."""
        return "rayscan"

    def name(self):
        """The name in the toolbox."""
        return "rayscan"

    def longName(self):  # noqa: N802 (QGIS's name)
        """The name with the executable's location."""
        return "rayscan point cloud ray queries"

    def icon(self):
        """QGIS's point cloud icon."""
        return QgsApplication.getThemeIcon("/mIconPointCloudLayer.svg")

    def load(self):
        """Add the executable option to Settings > Options > Processing > Providers, then the algorithms."""
        if ProcessingConfig is not None:
            ProcessingConfig.settingIcons[self.name()] = self.icon()
            ProcessingConfig.addSetting(Setting(
                self.name(), runner.EXECUTABLE_SETTING,
                "rayscan executable (empty: $RAYSCAN_EXECUTABLE, else rayscan on PATH)", "",
                valuetype=Setting.FILE))
            ProcessingConfig.readSettings()
        self.refreshAlgorithms()
        return True

    def unload(self):
        """Remove the option again."""
        if ProcessingConfig is not None:
            ProcessingConfig.removeSetting(runner.EXECUTABLE_SETTING)

    def loadAlgorithms(self):  # noqa: N802 (QGIS's name)
        """One instance of each algorithm class."""
        for cls in ALGORITHMS:
            self.addAlgorithm(cls())

    def supportedOutputRasterLayerExtensions(self):  # noqa: N802 (QGIS's name)
        """rayscan writes its maps as GeoTIFF only."""
        return ["tif"]

    def defaultRasterFileExtension(self):  # noqa: N802 (QGIS's name)
        """GeoTIFF, the only raster format rayscan writes."""
        return "tif"
