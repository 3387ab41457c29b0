"""What the rayscan algorithms share: the cloud input, naming, running the CLI, loading outputs."""

import csv
import os

from qgis.core import (QgsFeature, QgsFeatureSink, QgsField, QgsFields, QgsGeometry, QgsPoint,
                       QgsProcessing, QgsProcessingAlgorithm, QgsProcessingContext,
                       QgsProcessingException, QgsProcessingOutputLayerDefinition,
                       QgsProcessingParameterDefinition, QgsProcessingParameterEnum,
                       QgsProcessingParameterFile, QgsProcessingParameterNumber, QgsProcessingUtils,
                       QgsProperty, QgsProviderRegistry, QgsWkbTypes)
from qgis.PyQt.QtCore import QCoreApplication, QVariant

from .. import runner

# The file names rayscan takes, by extension. The plugin declares its parameters before it may run
# rayscan (the executable is found only when an algorithm runs), so these are copies of the
# library's lists, which tests/qgis compares with the ones rayscan's own refusals print.
#: The point cloud files rayscan reads (io::point_cloud_input_extensions) and its index files.
CLOUD_EXTENSIONS = (".las", ".laz", ".copc.laz", ".copc", ".ply", ".pcd", ".xyz", ".csv", ".txt", ".pts",
                    ".f64", ".rsi")
#: The per-point outputs rayscan writes (io::point_cloud_output_extensions).
POINTS_EXTENSIONS = (".las", ".laz", ".ply", ".pcd", ".xyz", ".csv", ".txt")
#: The images `rayscan render --out` writes (render::image_extensions).
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".exr")
#: The GeoTIFF maps rayscan writes (analysis::geotiff_extensions).
GEOTIFF_EXTENSIONS = (".tif", ".tiff")

#: The file dialog's filter of CLOUD_EXTENSIONS, each in lower and upper case (rayscan takes either).
CLOUD_FILTER = "Point clouds ({});;All files (*.*)".format(
    " ".join("*{} *{}".format(e, e.upper()) for e in CLOUD_EXTENSIONS))
#: The file dialog's filter of POINTS_EXTENSIONS, one format each.
POINTS_FILTER = ";;".join("{} (*{})".format(e[1:].upper(), e) for e in POINTS_EXTENSIONS)
#: The file dialog's filter of IMAGE_EXTENSIONS (the first, PNG, is the default).
IMAGE_FILTER = "Images ({})".format(" ".join("*" + e for e in IMAGE_EXTENSIONS))
#: The values of `--primitive` (render, visibility, solar), numbered alike in every algorithm's
#: PRIMITIVE so that one index means one geometry in models and scripts.
PRIMITIVES = ["surfel", "sphere"]


class RayscanAlgorithm(QgsProcessingAlgorithm):
    """Base of the rayscan algorithms: subclasses set NAME, DISPLAY and HELP and define the rest."""

    NAME = ""
    DISPLAY = ""
    HELP = ""
    INPUT = "INPUT"
    #: The rayscan options the algorithm sets from its parameters, defined once: parameter name ->
    #: the option's spellings as the CLI declares them, comma-separated ("--lat,--latitude"). The
    #: first spelling goes on the command line (option(), flag()); rayscan's refusals name an option
    #: as it was given (an option not given by one of its spellings), and run_cli replaces each
    #: spelling by the parameter (option_labels()).
    FLAGS = {}

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

    def add_cell_parameter(self):
        """Add the raster cell size (CELL, in the cloud's horizontal units, > 0)."""
        self.addParameter(QgsProcessingParameterNumber(
            "CELL", self.tr("Cell size (cloud units)"), QgsProcessingParameterNumber.Double, 1.0,
            minValue=1e-9))

    def add_spp_parameter(self):
        """Add the path tracer's samples per pixel (SPP, 1 .. 2^20, default 16 as the CLI)."""
        self.addParameter(QgsProcessingParameterNumber(
            "SPP", self.tr("Samples per pixel"), QgsProcessingParameterNumber.Integer, 16,
            minValue=1, maxValue=1048576))

    def add_primitive_parameter(self, description, default, advanced=False):
        """Add PRIMITIVE, an enum over PRIMITIVES (rayscan's `--primitive`), defaulting to ``default``."""
        p = QgsProcessingParameterEnum("PRIMITIVE", self.tr(description), PRIMITIVES,
                                       defaultValue=PRIMITIVES.index(default))
        if advanced:
            p.setFlags(p.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
        self.addParameter(p)

    def flag(self, name):
        """The command-line option that parameter ``name`` sets (the first spelling in FLAGS)."""
        return self.FLAGS[name].split(",")[0]

    def option(self, name, value):
        """``[flag, value]``: the option that parameter ``name`` sets, with ``value``."""
        return [self.flag(name), value]

    def label(self, name):
        """Parameter ``name`` as the user sees it in messages: "Description [NAME]"."""
        return "{} [{}]".format(self.parameterDefinition(name).description(), name)

    def option_labels(self):
        """Each spelling of each option in FLAGS -> its parameter as the user sees it (label())."""
        labels = {}
        for name, spellings in self.FLAGS.items():
            for spelling in spellings.split(","):
                labels[spelling] = self.label(name)
        return labels

    def given_number(self, parameters, name, context):
        """Optional number parameter ``name``: its value, or None when left empty (the CLI's default)."""
        given = parameters.get(name)
        if given is None or str(given) in ("", "NULL"):
            return None
        return self.parameterAsDouble(parameters, name, context)

    def sink_requested(self, parameters, name, context):
        """Whether optional feature sink ``name`` is asked for, known before rayscan runs: not when
        its value is missing, None, NULL, "" or an output definition naming "" and the parameter has no
        default, the values for which parameterAsSink makes no sink.

        (parameterAsOutputLayer would tell the same, but also queues a layer to load into the
        project when the output is to be opened.)
        """
        value = parameters.get(name)
        if isinstance(value, QgsProcessingOutputLayerDefinition):
            value = value.sink
        if isinstance(value, QgsProperty):
            value = value.valueAsString(context.expressionContext())[0]
        if isinstance(value, QVariant):  # NULL
            value = None if value.isNull() else value.value()
        if value is None or str(value) == "":
            value = self.parameterDefinition(name).defaultValue()
        return value is not None and str(value) != ""

    def cloud(self, parameters, context):
        """The point cloud path of INPUT, checked to exist."""
        path = self.parameterAsFile(parameters, self.INPUT, context)
        if not path or not os.path.isfile(path):
            raise QgsProcessingException(self.tr("Point cloud file not found: {}").format(path))
        return path

    def run_cli(self, args, feedback, rewrite=None):
        """Run ``rayscan ARGS`` with the feedback's progress and cancellation; return stdout.

        A refusal (QgsProcessingException) names the algorithm's parameters where rayscan names
        the options of FLAGS, after ``rewrite`` (see runner.run_rayscan) has put the files the
        plugin wrote for rayscan in the user's terms. (Not named ``run``: that is
        QgsProcessingAlgorithm.run, which processing.run and the batch dialog call.)
        """
        return runner.run_rayscan(args, feedback, labels=self.option_labels(), rewrite=rewrite)

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

    def load_cloud_on_completion(self, path, name, output, context, feedback):
        """Load LAS/LAZ output ``path`` as a point cloud layer where QGIS reads LAS (its PDAL provider).

        Debian 12's QGIS 3.22 is built without PDAL; there the cloud is left on disk and the log
        says so (the point vector layer output shows the results in QGIS instead).
        """
        if not path.lower().endswith((".las", ".laz")):
            return
        if QgsProviderRegistry.instance().providerMetadata("pdal") is None:
            feedback.pushInfo(self.tr("{}: this QGIS has no PDAL provider to open LAS/LAZ as a layer").format(path))
            return
        self.load_on_completion(path, name, output, context, QgsProcessingUtils.LayerHint.PointCloud)

    def cloud_to_sink(self, cloud_file, parameters, sink_name, crs, context, feedback):
        """Copy the points of ``cloud_file`` (with every field) into feature sink ``sink_name``; return its id.

        rayscan translate writes the cloud as CSV (x, y, z, then each attribute), read back here
        as PointZ features with one double field per attribute.
        """
        text = QgsProcessingUtils.generateTempFilename("points.csv")
        try:
            return self._csv_to_sink(text, cloud_file, parameters, sink_name, crs, context, feedback)
        finally:
            if os.path.exists(text):
                os.remove(text)

    def _csv_to_sink(self, text, cloud_file, parameters, sink_name, crs, context, feedback):
        """cloud_to_sink's work, through the temporary CSV file ``text`` (removed by the caller)."""
        runner.run_rayscan(["translate", cloud_file, text], feedback)
        with open(text, newline="", encoding="utf-8") as f:
            total = max(1, sum(1 for _ in f) - 1)
        with open(text, newline="", encoding="utf-8") as f:
            rows = csv.reader(f)
            header = next(rows)
            if header[:3] != ["x", "y", "z"]:
                raise QgsProcessingException("{}: unexpected columns {}".format(text, header[:3]))
            fields = QgsFields()
            for name in header[3:]:
                fields.append(QgsField(name, QVariant.Double))
            sink, dest_id = self.parameterAsSink(parameters, sink_name, context, fields,
                                                 QgsWkbTypes.PointZ, crs)
            if sink is None:
                raise QgsProcessingException(self.invalidSinkError(parameters, sink_name))
            feedback.pushInfo(self.tr("Writing {} points to the vector layer").format(total))
            feature = QgsFeature(fields)
            try:
                for i, row in enumerate(rows):
                    if i % 10000 == 0:
                        if feedback.isCanceled():
                            # A canceled run is an error, so Processing neither reports success nor
                            # loads the part written so far.
                            raise QgsProcessingException(self.tr("Canceled while writing {}").format(sink_name))
                        feedback.setProgress(100.0 * i / total)
                    feature.setGeometry(QgsGeometry(QgsPoint(float(row[0]), float(row[1]), float(row[2]))))
                    feature.setAttributes([float(v) for v in row[3:]])
                    sink.addFeature(feature, QgsFeatureSink.FastInsert)
            except BaseException:
                sink = None  # the last reference: the writer closes the file, which can then go
                remove_partial_file(dest_id, feedback)
                raise
        return dest_id


def remove_partial_file(dest_id, feedback):
    """Delete the vector file a sink was writing when its run stopped (cancel or error), so that no
    half-written layer (a GeoPackage without its table and with its -journal) is left at the
    user's path, as rayscan leaves no partial output file.

    Only a destination that is a file of its own: a memory layer or a layer inside a database
    ("|layername=") is left to Processing. GDAL's driver deletes the dataset with its sidecar
    files (a shapefile's .dbf, .shx, .prj).
    """
    if not dest_id or "|" in dest_id or not os.path.isfile(dest_id):
        return
    try:
        from osgeo import gdal
        driver = gdal.IdentifyDriverEx(dest_id, gdal.OF_VECTOR)
        if driver is not None:
            driver.Delete(dest_id)
    except (ImportError, RuntimeError):  # RuntimeError: GDAL's failure where gdal.UseExceptions() is on
        pass
    for path in (dest_id, dest_id + "-journal", dest_id + "-wal", dest_id + "-shm"):
        if os.path.exists(path):
            try:
                os.remove(path)
            except OSError as e:
                feedback.pushWarning("Cannot remove the partial file {}: {}".format(path, e))
