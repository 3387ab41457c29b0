"""rayscan Processing: QGIS Processing algorithms that run the rayscan command-line tool."""


def classFactory(iface):  # noqa: N802 (QGIS's name)
    """Return the plugin instance QGIS loads (``iface`` is None under qgis_process)."""
    from .plugin import RayscanProcessingPlugin

    return RayscanProcessingPlugin(iface)
