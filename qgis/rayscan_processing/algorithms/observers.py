"""The observer point layer of the visibility algorithms, written as the CSV `rayscan visibility --observers` reads."""

import csv
import math

from qgis.core import (QgsCoordinateTransform, QgsFeatureRequest, QgsPointXY, QgsProcessing,
                       QgsProcessingException, QgsProcessingParameterBoolean,
                       QgsProcessingParameterFeatureSource, QgsProcessingParameterField,
                       QgsProcessingParameterNumber, QgsProcessingUtils, QgsWkbTypes)

from .. import runner

OBSERVERS = "OBSERVERS"
HEIGHT = "HEIGHT"
HEIGHT_FIELD = "HEIGHT_FIELD"
USE_Z = "USE_Z"


def add_observer_parameters(alg):
    """Add the observer layer, eye height, per-observer height field and absolute-Z switch to ``alg``."""
    alg.addParameter(QgsProcessingParameterFeatureSource(
        OBSERVERS, alg.tr("Observers (points)"), [QgsProcessing.TypeVectorPoint]))
    alg.addParameter(QgsProcessingParameterNumber(
        HEIGHT, alg.tr("Eye height above the local ground (cloud units)"),
        QgsProcessingParameterNumber.Double, 1.7))
    alg.addParameter(QgsProcessingParameterField(
        HEIGHT_FIELD, alg.tr("Eye height field (per observer; empty values use the height above)"),
        parentLayerParameterName=OBSERVERS, type=QgsProcessingParameterField.Numeric, optional=True))
    alg.addParameter(QgsProcessingParameterBoolean(
        USE_Z, alg.tr("The observers' Z is the absolute eye elevation, in the cloud's vertical units "
                      "(the heights are then unused)"),
        defaultValue=False))


def _same_place(transform, extent):
    """Whether ``transform`` leaves two points of ``extent`` where they are (two spellings of one CRS).

    A GeoPackage's WKT and a LAS file's WKT of one CRS compare unequal in QGIS, yet PROJ's
    pipeline between them is a no-op; skipping it keeps the coordinates bit for bit.
    """
    c = extent.center()
    for p in (QgsPointXY(c.x(), c.y()), QgsPointXY(c.x() + extent.width() + 1000.0, c.y() + extent.height() + 1000.0)):
        try:
            q = transform.transform(p)
        except Exception:  # noqa: BLE001 (a point outside the CRS's area: not the same CRS)
            return False
        if abs(q.x() - p.x()) > 1e-7 or abs(q.y() - p.y()) > 1e-7:
            return False
    return True


def write_observers(alg, parameters, context, feedback, cloud):
    """Write the observers to a temporary CSV in the CRS of the point cloud file `cloud`; return
    (path, the cloud's CRS).

    The layer is reprojected to the cloud's CRS when both are known and differ, as rayscan reads
    observer coordinates in the cloud's own coordinates; a layer without a CRS is taken to be in
    the cloud's, with a warning naming the layer. Raises QgsProcessingException for a
    missing layer, a layer without Z when USE_Z is set, or a layer without points.
    """
    source = alg.parameterAsSource(parameters, OBSERVERS, context)
    if source is None:
        raise QgsProcessingException(alg.invalidSourceError(parameters, OBSERVERS))
    height = alg.parameterAsDouble(parameters, HEIGHT, context)
    field = alg.parameterAsString(parameters, HEIGHT_FIELD, context)
    use_z = alg.parameterAsBool(parameters, USE_Z, context)
    if use_z and not QgsWkbTypes.hasZ(source.wkbType()):
        raise QgsProcessingException(alg.tr("The observer layer has no Z values"))

    target = runner.cloud_crs(cloud, feedback)
    transform = None
    if target.isValid() and not source.sourceCrs().isValid():
        # As QGIS's own algorithms do (an unknown CRS matches any, a transform from it does
        # nothing), but said, since a layer in other coordinates lands elsewhere or nowhere.
        feedback.pushWarning(alg.tr("Observer layer '{}' has no CRS: its coordinates are taken to be in the "
                                    "cloud's CRS {}").format(source.sourceName(), target.userFriendlyIdentifier()))
    elif target.isValid() and source.sourceCrs() != target:
        transform = QgsCoordinateTransform(source.sourceCrs(), target, context.transformContext())
        if _same_place(transform, source.sourceExtent()):
            transform = None
        else:
            feedback.pushInfo(alg.tr("Observers reprojected from {} to the cloud's CRS {}").format(
                source.sourceCrs().userFriendlyIdentifier(), target.userFriendlyIdentifier()))

    path = QgsProcessingUtils.generateTempFilename("observers.csv")
    count = 0
    with open(path, "w", newline="", encoding="utf-8") as f:
        out = csv.writer(f)
        # rayscan takes either an absolute eye (z) or a height above the local ground, never both.
        out.writerow(["x", "y", "z", "name"] if use_z else ["x", "y", "height", "name"])
        for feature in source.getFeatures(QgsFeatureRequest()):
            if feedback.isCanceled():
                raise QgsProcessingException(alg.tr("Canceled while reading the observers"))
            geometry = feature.geometry()
            if geometry.isNull() or geometry.isEmpty():
                feedback.pushWarning(alg.tr("Observer {} has no geometry: skipped").format(feature.id()))
                continue
            if transform is not None:
                geometry.transform(transform)
            h = height
            if field:
                value = feature[field]
                if value is not None and str(value) != "NULL":
                    try:
                        h = float(value)
                    except (TypeError, ValueError):
                        h = math.nan
                    if not math.isfinite(h):
                        raise QgsProcessingException(alg.tr(
                            "Height field '{}' of observer {}: '{}' is not a finite number (eye height, "
                            "cloud units)").format(field, feature.id(), value))
            for part, vertex in enumerate(geometry.vertices()):
                if not (math.isfinite(vertex.x()) and math.isfinite(vertex.y())):
                    continue
                name = str(feature.id()) if part == 0 else "{}.{}".format(feature.id(), part)
                row = [repr(vertex.x()), repr(vertex.y()), repr(vertex.z() if use_z else h), name]
                out.writerow(row)
                count += 1
    if count == 0:
        raise QgsProcessingException(alg.tr("The observer layer has no points"))
    feedback.pushInfo(alg.tr("{} observers").format(count))
    return path, target
