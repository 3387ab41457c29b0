"""What the rayscan algorithms share: the cloud input, naming, running the CLI, loading outputs."""

import os

from qgis.core import (QgsProcessing, QgsProcessingAlgorithm, QgsProcessingContext,
                       QgsProcessingException, QgsProcessingParameterFile, QgsProcessingUtils)
from qgis.PyQt.QtCore import QCoreApplication

from .. import runner

#: The point cloud files rayscan reads (`rayscan info --help`).
CLOUD_FILTER = ("Point clouds (*.las *.LAS *.laz *.LAZ *.copc.laz *.ply *.pcd *.xyz *.csv *.txt *.rsi);;"
                "All files (*.*)")
#: The per-point outputs rayscan writes, by extension.
POINTS_FILTER = "LAS (*.las);;LAZ (*.laz);;PLY (*.ply);;PCD (*.pcd);;CSV (*.csv);;XYZ (*.xyz)"


class RayscanAlgorithm(QgsProcessingAlgorithm):
    """Base of the rayscan algorithms: subclasses set NAME, DISPLAY and HELP and define the rest."""

    NAME = ""
    DISPLAY = ""
    HELP = ""
    INPUT = "INPUT"

    def tr(self, text):
        """Translate ``text`` in the plugin's context."""
        return QCoreApplication.translate("rayscan", text)

    def createInstance(self):  # noqa: N802 (QGIS's name)
        """A fresh copy, as Processing runs each execution on its own instance."""
        return type(self)()

    def name(self):
        """The id after ``rayscan:``."""
        return self.NAME

    def displayName(self):  # noqa: N802 (QGIS's name)
        """The name shown in the toolbox."""
        return self.tr(self.DISPLAY)

    def group(self):
        """The toolbox group."""
        return self.tr("Point cloud")

    def groupId(self):  # noqa: N802 (QGIS's name)
        """The toolbox group's id."""
        return "pointcloud"

    def shortHelpString(self):  # noqa: N802 (QGIS's name)
        """The help shown beside the dialog."""
        return self.tr(self.HELP)

    def add_cloud_parameter(self):
        """Add the point cloud file input (INPUT)."""
        self.addParameter(QgsProcessingParameterFile(
            self.INPUT, self.tr("Point cloud (LAS, LAZ, COPC, PLY, PCD, text, rayscan index)"),
            behavior=QgsProcessingParameterFile.File, fileFilter=CLOUD_FILTER))

    def cloud(self, parameters, context):
        """The point cloud path of INPUT, checked to exist."""
        path = self.parameterAsFile(parameters, self.INPUT, context)
        if not path or not os.path.isfile(path):
            raise QgsProcessingException(self.tr("Point cloud file not found: {}").format(path))
        return path

    def run(self, args, feedback):
        """Run ``rayscan ARGS`` with the feedback's progress and cancellation; return stdout."""
        return runner.run_rayscan(args, feedback)

    @staticmethod
    def check_extension(path, extensions, what):
        """Raise QgsProcessingException unless ``path`` ends with one of ``extensions``."""
        if not path.lower().endswith(tuple(extensions)):
            raise QgsProcessingException("{} must be a {} file: {}".format(what, " or ".join(extensions), path))

    def load_on_completion(self, path, name, output, context, hint):
        """Load file output ``path`` as a layer when the algorithm ends (file destinations are not loaded by Processing itself)."""
        if not path or path == QgsProcessing.TEMPORARY_OUTPUT or not os.path.exists(path):
            return
        details = QgsProcessingContext.LayerDetails(name, context.project(), output)
        details.layerTypeHint = hint
        context.addLayerToLoadOnCompletion(path, details)

    @staticmethod
    def point_cloud_hint():
        """The layer-type hint for a point cloud file, or UnknownType where QGIS has none."""
        return getattr(QgsProcessingUtils.LayerHint, "PointCloud", QgsProcessingUtils.LayerHint.UnknownType)
