"""The plugin object: registers the rayscan Processing provider with QGIS."""

from qgis.core import QgsApplication


class RayscanProcessingPlugin:
    """Adds the ``rayscan`` provider to the Processing registry while the plugin is loaded."""

    def __init__(self, iface):
        """Keep ``iface`` (None when loaded by qgis_process, which has no GUI)."""
        self.iface = iface
        self.provider = None

    def initProcessing(self):  # noqa: N802 (QGIS's name)
        """Register the provider; qgis_process calls this without initGui."""
        from .provider import RayscanProvider

        if self.provider is None:
            self.provider = RayscanProvider()
            QgsApplication.processingRegistry().addProvider(self.provider)

    def initGui(self):  # noqa: N802 (QGIS's name)
        """Register the provider in the desktop application (no menus of its own)."""
        self.initProcessing()

    def unload(self):
        """Remove the provider when the plugin is disabled or reloaded."""
        if self.provider is not None:
            QgsApplication.processingRegistry().removeProvider(self.provider)
            self.provider = None
