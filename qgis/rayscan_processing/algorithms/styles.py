"""Styles of the 0/1 rasters rayscan writes (a viewshed, a shadow map), for the layers Processing loads."""

from qgis.core import QgsPalettedRasterRenderer, QgsProcessingLayerPostProcessorInterface
from qgis.PyQt.QtGui import QColor

#: `rayscan visibility --raster-value viewshed` and `viewshed-points`: 1 where an observer sees
#: the cell, 0 where none does. Each class: (value, label, colour).
SEEN = ((0, "not seen", "#4d4d4d"), (1, "seen", "#4dac26"))
#: `rayscan solar --raster-value in_shadow`: 1 where the cell is in the shadow of the points, 0 in sun.
SHADOW = ((0, "sun", "#fdd835"), (1, "shadow", "#283593"))


def apply_classes(layer, classes):
    """Give raster ``layer`` (band 1) a paletted style of ``classes`` ((value, label, colour), as
    SEEN), so that it draws as named classes instead of a grey stretch; NoData stays transparent."""
    renderer = QgsPalettedRasterRenderer(
        layer.dataProvider(), 1,
        [QgsPalettedRasterRenderer.Class(value, QColor(colour), label) for value, label, colour in classes])
    layer.setRenderer(renderer)
    layer.triggerRepaint()


class ClassStyle(QgsProcessingLayerPostProcessorInterface):
    """Styles a loaded output with apply_classes. Make one with create()."""

    # QGIS owns the C++ side of a post-processor, but the Python object that overrides
    # postProcessLayer is dropped with the LayerDetails wrapper it was handed to (the output then
    # loads unstyled); so each is held here, for the session (one small object per run).
    _held = []

    def __init__(self, classes):
        """``classes``: as apply_classes takes them."""
        super().__init__()
        self.classes = classes

    @staticmethod
    def create(classes):
        """A new post-processor for ``classes``, held for the session."""
        processor = ClassStyle(classes)
        ClassStyle._held.append(processor)
        return processor

    def postProcessLayer(self, layer, context, feedback):  # noqa: N802 (QGIS's name)
        """Style ``layer`` once Processing has loaded it into the project."""
        apply_classes(layer, self.classes)


def style_on_completion(path, classes, context):
    """Give output ``path`` the paletted style of ``classes`` when Processing loads it into a project
    (the dialog's "Open output file after running"); nothing when it is not loaded (qgis_process,
    processing.run without a project)."""
    if context.willLoadLayerOnCompletion(path):
        context.layerToLoadOnCompletionDetails(path).setPostProcessor(ClassStyle.create(classes))
