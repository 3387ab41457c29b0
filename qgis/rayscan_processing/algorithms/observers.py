"""The observer point layer of the visibility algorithms, written as the CSV `rayscan visibility --observers` reads."""

import csv
import math
import os
import re

from qgis.core import (QgsCoordinateTransform, QgsCsException, QgsFeatureRequest, QgsPointXY, QgsProcessing,
                       QgsProcessingException, QgsProcessingParameterBoolean,
                       QgsProcessingParameterDefinition, QgsProcessingParameterFeatureSource,
                       QgsProcessingParameterField, QgsProcessingParameterNumber, QgsProcessingUtils,
                       QgsUnitTypes, QgsWkbTypes)

from .. import runner

OBSERVERS = "OBSERVERS"
HEIGHT = "HEIGHT"
HEIGHT_FIELD = "HEIGHT_FIELD"
USE_Z = "USE_Z"
GROUND_RADIUS = "GROUND_RADIUS"
#: The rayscan options the observer parameters set, for the algorithms' FLAGS.
FLAGS = {OBSERVERS: "--observers", GROUND_RADIUS: "--ground-radius"}


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
    # Empty leaves rayscan's own default (5 x the point radius, the ground right under the eye
    # first with surfels), which a plugin default could only copy, not follow.
    ground = QgsProcessingParameterNumber(
        GROUND_RADIUS, alg.tr("Local ground search radius (cloud units; empty = 5 x the point radius)"),
        QgsProcessingParameterNumber.Double, None, True, 1e-9)
    ground.setFlags(ground.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
    alg.addParameter(ground)


def observer_args(alg, parameters, context, observers):
    """The observer options of the command line: ``--observers`` with the CSV of ``observers`` (an
    ObserverFile) and ``--ground-radius`` when GROUND_RADIUS is given."""
    args = alg.option(OBSERVERS, observers.path)
    ground = alg.given_number(parameters, GROUND_RADIUS, context)
    if ground is not None:
        args += alg.option(GROUND_RADIUS, ground)
    return args


class ObserverFile:
    """The observers as written for rayscan (write_observers): the CSV's ``path``, ``crs`` (the CRS
    of the run's layers, runner.cloud_crs) and, to put rayscan's messages in the layer's terms,
    the feature and part each CSV line came from. The CSV is the caller's to remove (remove())
    once rayscan has read it."""

    def __init__(self, path, crs, where, lines):
        """``where``: the layer as messages name it; ``lines``: CSV line number -> (feature id, part)."""
        self.path, self.crs, self.where, self.lines = path, crs, where, lines

    def remove(self):
        """Delete the CSV: it holds the observers' coordinates, and Processing's temporary folder
        lives as long as the QGIS session."""
        _remove(self.path)

    def user_terms(self, line):
        """Line ``line`` of rayscan's with "CSV: line N: observer 'NAME'" written as the layer and
        feature of that line ("Observers (points) [OBSERVERS] 'far', feature 3"), and any other
        mention of the CSV as the layer: the CSV is a temporary file the user never sees."""
        def feature(m):
            fid, part = self.lines.get(int(m.group(1)), (None, 0))
            if fid is None:
                return m.group(0)
            return "{}, feature {}{}".format(self.where, fid, ", point {}".format(part + 1) if part else "")
        line = re.sub(re.escape(self.path) + r": line (\d+): observer '[^']*'", feature, line)
        return line.replace(self.path, self.where)


def _remove(path):
    """Delete file ``path`` when it exists."""
    if os.path.exists(path):
        os.remove(path)


def eye_height_note(alg, crs, height, field):
    """(warn, text): the eye height HEIGHT (``height``; and HEIGHT_FIELD ``field``'s values when
    given) with the unit it is in, the map unit of the cloud's CRS ``crs`` (runner.cloud_crs).
    ``warn`` when that unit is known and not metres: the default 1.7 reads as metres, yet it is
    1.7 feet (0.52 m) for a cloud in feet. The value stays as the user gave it.
    """
    given = "{} {:g}".format(alg.label(HEIGHT), height)
    also = " (and the values of {} '{}')".format(HEIGHT_FIELD, field) if field else ""
    unit = crs.mapUnits() if crs.isValid() else QgsUnitTypes.DistanceUnknownUnit
    if unit in (QgsUnitTypes.DistanceUnknownUnit, QgsUnitTypes.DistanceDegrees):
        return False, alg.tr("{}{}: in the cloud's own units").format(given, also)
    name = QgsUnitTypes.toString(unit)
    if unit == QgsUnitTypes.DistanceMeters:
        return False, alg.tr("{}{}: {}, the unit of the cloud's CRS").format(given, also, name)
    metres = height * QgsUnitTypes.fromUnitToUnitFactor(unit, QgsUnitTypes.DistanceMeters)
    return True, alg.tr("{}{} is in {}, the unit of the cloud's CRS {}: {:g} {} = {:.3g} m").format(
        given, also, name, crs.userFriendlyIdentifier(), height, name, metres)


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


def _transform_error(where, fid, point, source, target):
    """The error for feature ``fid`` of the observer layer whose ``point`` QGIS cannot take from CRS
    ``source`` to ``target``: most often a layer whose CRS is not the one its coordinates are in."""
    return QgsProcessingException(
        "{}, feature {}: ({}, {}) cannot be transformed from {} to the cloud's CRS {}; are the layer's "
        "coordinates in its CRS?".format(where, fid, repr(point.x()), repr(point.y()),
                                         source.userFriendlyIdentifier(), target.userFriendlyIdentifier()))


def write_observers(alg, parameters, context, feedback, cloud):
    """Write the observers to a temporary CSV in the CRS of the point cloud file `cloud`; return an
    ObserverFile.

    The layer is reprojected to the cloud's CRS when both are known and differ, as rayscan reads
    observer coordinates in the cloud's own coordinates: to the CRS QGIS reads from rayscan's
    rasters (runner.cloud_crs), so the observers sit on the run's outputs in any project CRS. A
    layer whose coordinates are the cloud's own (its WKT, or the rasters' CRS) is not transformed.
    A layer without a CRS is taken to be in the cloud's, with a warning naming the layer. Raises
    QgsProcessingException for a missing layer, a HEIGHT_FIELD the layer lacks, a layer without Z
    when USE_Z is set, a point QGIS cannot transform (naming the feature and both CRSs), or a
    layer without points.
    """
    source = alg.parameterAsSource(parameters, OBSERVERS, context)
    if source is None:
        raise QgsProcessingException(alg.invalidSourceError(parameters, OBSERVERS))
    where = "{} '{}'".format(alg.label(OBSERVERS), source.sourceName())
    height = alg.parameterAsDouble(parameters, HEIGHT, context)
    field = alg.parameterAsString(parameters, HEIGHT_FIELD, context)
    use_z = alg.parameterAsBool(parameters, USE_Z, context)
    if field and source.fields().lookupField(field) < 0:
        numeric = [f.name() for f in source.fields() if f.isNumeric()]
        raise QgsProcessingException(alg.tr("{} '{}' is not a field of {}; {}").format(
            alg.label(HEIGHT_FIELD), field, where,
            "its numeric fields: " + ", ".join(numeric) if numeric else "it has no numeric field"))
    if use_z and not QgsWkbTypes.hasZ(source.wkbType()):
        raise QgsProcessingException(alg.tr("The observer layer has no Z values"))

    own, target = runner.cloud_crs(cloud, feedback)
    if not use_z:
        warn, note = eye_height_note(alg, target, height, field)
        (feedback.pushWarning if warn else feedback.pushInfo)(note)
    transform = None
    if target.isValid() and not source.sourceCrs().isValid():
        # As QGIS's own algorithms do (an unknown CRS matches any, a transform from it does
        # nothing), but said, since a layer in other coordinates lands elsewhere or nowhere.
        feedback.pushWarning(alg.tr("Observer layer '{}' has no CRS: its coordinates are taken to be in the "
                                    "cloud's CRS {}").format(source.sourceName(), target.userFriendlyIdentifier()))
    elif target.isValid() and source.sourceCrs() != target:
        transform = QgsCoordinateTransform(source.sourceCrs(), target, context.transformContext())
        extent = source.sourceExtent()
        if (_same_place(QgsCoordinateTransform(source.sourceCrs(), own, context.transformContext()), extent)
                or _same_place(transform, extent)):
            transform = None
        else:
            feedback.pushInfo(alg.tr("Observers reprojected from {} to the cloud's CRS {}").format(
                source.sourceCrs().userFriendlyIdentifier(), target.userFriendlyIdentifier()))

    path = QgsProcessingUtils.generateTempFilename("observers.csv")
    try:
        lines = _write_csv(alg, path, source, feedback, transform, target, where, height, field, use_z)
    except BaseException:
        _remove(path)
        raise
    feedback.pushInfo(alg.tr("{} observers").format(len(lines)))
    return ObserverFile(path, target, where, lines)


def _write_csv(alg, path, source, feedback, transform, target, where, height, field, use_z):
    """write_observers' CSV at ``path``; return its line number -> (feature id, part). Raises as
    write_observers describes (the caller removes the file then)."""
    lines = {}
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
                try:
                    geometry.transform(transform)
                except QgsCsException:
                    raise _transform_error(where, feature.id(), feature.geometry().vertexAt(0),
                                           source.sourceCrs(), target) from None
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
                    if transform is not None:  # PROJ's HUGE_VAL for a point outside its domain
                        raise _transform_error(where, feature.id(), feature.geometry().vertexAt(part),
                                               source.sourceCrs(), target)
                    continue
                name = str(feature.id()) if part == 0 else "{}.{}".format(feature.id(), part)
                row = [repr(vertex.x()), repr(vertex.y()), repr(vertex.z() if use_z else h), name]
                out.writerow(row)
                lines[len(lines) + 2] = (feature.id(), part)  # line 1 is the header
    if not lines:
        raise QgsProcessingException(alg.tr("The observer layer has no points"))
    return lines
