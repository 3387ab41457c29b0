"""Running the rayscan executable from an algorithm: locating it, progress, cancellation, the cloud's CRS."""

import json
import os
import queue
import re
import shutil
import subprocess
import threading
import uuid

from qgis.core import QgsCoordinateReferenceSystem, QgsProcessingException, QgsRasterLayer, QgsSettings

from .cli_progress import parse_progress

#: Processing's option (Settings > Options > Processing > Providers > rayscan) and the
#: environment variable that name the executable; both empty means `rayscan` on PATH.
EXECUTABLE_SETTING = "RAYSCAN_EXECUTABLE"
EXECUTABLE_ENV = "RAYSCAN_EXECUTABLE"
# ProcessingConfig keeps provider options under this QgsSettings group; reading the key directly
# works in qgis_process and in worker threads alike.
_SETTINGS_KEY = "Processing/Configuration/" + EXECUTABLE_SETTING

# Seconds between SIGTERM and SIGKILL when a run is canceled.
_TERMINATE_GRACE_S = 5.0


def find_executable():
    """Return the rayscan executable: $RAYSCAN_EXECUTABLE, else the provider option, else PATH.

    Raises QgsProcessingException naming all three places when none holds a runnable program.
    """
    env = os.environ.get(EXECUTABLE_ENV, "").strip()
    option = str(QgsSettings().value(_SETTINGS_KEY, "") or "").strip()
    for origin, name in (("RAYSCAN_EXECUTABLE", env), ("the rayscan provider option", option)):
        if name:
            path = shutil.which(name) or (name if os.access(name, os.X_OK) and os.path.isfile(name) else None)
            if not path:
                raise QgsProcessingException(
                    "rayscan executable {!r} (from {}) does not exist or is not executable".format(name, origin))
            return path
    path = shutil.which("rayscan")
    if not path:
        raise QgsProcessingException(
            "The rayscan executable was not found: install the rayscan package (it provides "
            "/usr/bin/rayscan), put rayscan on PATH, set the environment variable RAYSCAN_EXECUTABLE, "
            "or set Settings > Options > Processing > Providers > rayscan > rayscan executable")
    return path


def _pump(stream, tag, out):
    """Copy the lines of ``stream`` into queue ``out`` as (tag, line); (tag, None) at the end."""
    for line in iter(stream.readline, ""):
        out.put((tag, line.rstrip("\n")))
    out.put((tag, None))


def name_options(line, labels):
    """Refusal ``line`` of rayscan in an algorithm's terms: each option spelling that ``labels`` maps
    (``--lat``, ``-o``) replaced by its label (the parameter), and CLI11's `` (see --help)`` dropped.

    A spelling is replaced only as a whole word, so ``--lat`` leaves ``--latitude`` (its own entry)
    and a path such as ``a--lat.las`` alone.
    """
    if line.endswith(" (see --help)"):
        line = line[:-len(" (see --help)")]
    if not labels:
        return line
    spellings = sorted(labels, key=len, reverse=True)
    pattern = r"(?<![\w-])(" + "|".join(re.escape(s) for s in spellings) + r")(?![\w-])"
    return re.sub(pattern, lambda m: labels[m.group(1)], line)


def run_rayscan(args, feedback, log_stdout=True, labels=None, rewrite=None):
    """Run ``rayscan ARGS``; return its standard output.

    Standard error goes to the feedback's log (its options named by ``labels`` as in the error
    below, each line first passed through ``rewrite`` when given, which puts what the plugin
    wrote for rayscan, such as the observers' CSV, in the user's terms), and its progress lines to
    ``feedback.setProgress``.
    When the feedback is canceled the process is terminated (then killed after a grace period) and
    QgsProcessingException is raised; nothing it wrote is deleted: rayscan moves each output into
    place only when it is complete, so a canceled run leaves the earlier file, or none.
    A non-zero exit raises QgsProcessingException: rayscan's own one-line error for exit status 2
    (its last line of standard error, rewritten and its options named by ``labels``: see
    name_options), else the status and the last lines of standard error.
    """
    def user_terms(line):
        """A line of rayscan's standard error in the algorithm's terms."""
        return name_options(rewrite(line) if rewrite else line, labels)

    cmd = [find_executable()] + [str(a) for a in args]
    if feedback is not None:
        feedback.pushCommandInfo(subprocess.list2cmdline(cmd))
    try:
        proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, universal_newlines=True, bufsize=1)
    except OSError as e:
        raise QgsProcessingException("cannot run {}: {}".format(cmd[0], e))
    with proc:
        lines = queue.Queue()
        for stream, tag in ((proc.stdout, "out"), (proc.stderr, "err")):
            threading.Thread(target=_pump, args=(stream, tag, lines), daemon=True).start()
        out, err_tail, open_streams, canceled = [], [], 2, False
        while open_streams:
            if feedback is not None and feedback.isCanceled() and not canceled:
                canceled = True
                proc.terminate()
                try:
                    proc.wait(_TERMINATE_GRACE_S)
                except subprocess.TimeoutExpired:
                    proc.kill()
            try:
                tag, line = lines.get(timeout=0.2)
            except queue.Empty:
                continue
            if line is None:
                open_streams -= 1
            elif tag == "out":
                out.append(line)
                if log_stdout and feedback is not None:
                    feedback.pushConsoleInfo(line)
            else:
                err_tail = (err_tail + [line])[-20:]
                pct = parse_progress(line)
                if feedback is None:
                    pass
                elif pct is not None:
                    feedback.setProgress(pct)
                else:
                    feedback.pushConsoleInfo(user_terms(line))
        code = proc.wait()
    if canceled:
        raise QgsProcessingException("rayscan was canceled")
    if code != 0:
        # Exit status 2 is a refusal whose reason is rayscan's last line ("rayscan COMMAND: ..."):
        # that line alone, without the log and progress lines before it. Any other status (a crash,
        # a kill) with the tail, since its last line may be an ordinary log line.
        if code == 2 and err_tail and err_tail[-1].startswith("rayscan "):
            raise QgsProcessingException(user_terms(err_tail[-1]))
        raise QgsProcessingException("rayscan exited with status {}:\n{}".format(code, "\n".join(err_tail)))
    return "\n".join(out)


def cloud_crs(cloud, feedback=None):
    """Return (own, layers): the CRS of point cloud file ``cloud`` as ``rayscan info --json`` gives
    it (its WKT read by QGIS), and the same CRS as QGIS reads it from a GeoTIFF rayscan writes (see
    geotiff_crs); both invalid when the cloud has none (the feedback then warns).

    ``own`` says whether a layer's coordinates are already the cloud's; ``layers`` is the CRS every
    layer of a run is given, so that rayscan's rasters and the plugin's own layers are one CRS in
    QGIS. Raises QgsProcessingException when rayscan's output cannot be read.
    """
    text = run_rayscan(["info", "--json", cloud], None)
    try:
        crs = json.loads(text).get("crs") or {}
    except ValueError as e:
        raise QgsProcessingException("rayscan info --json {}: unreadable output ({})".format(cloud, e))
    for key in ("wkt2", "wkt"):
        if crs.get(key):
            own = QgsCoordinateReferenceSystem.fromWkt(crs[key])
            if own.isValid():
                return own, geotiff_crs(crs[key], own)
    if feedback is not None:
        feedback.pushWarning("{} has no CRS: coordinates are used as they are".format(cloud))
    return QgsCoordinateReferenceSystem(), QgsCoordinateReferenceSystem()


def geotiff_crs(wkt, fallback):
    """The CRS QGIS gives a GeoTIFF that rayscan writes with CRS ``wkt``; ``fallback`` when GDAL
    cannot write or QGIS cannot read such a file.

    QGIS identifies a GeoTIFF's CRS from its GeoKeys (autzen's LAS WKT comes back as EPSG:2994),
    and that CRS transforms to WGS 84 through another datum operation than the WKT does (about
    1.3 m apart for autzen). The vector layers and the observers' reprojection therefore take the
    CRS of a one-cell GeoTIFF written as rayscan writes its rasters (GDAL's GTiff driver,
    SetSpatialRef of the WKT in traditional GIS axis order) and opened as a QGIS raster layer, so
    that every layer of a run is the CRS QGIS sees on rayscan's rasters.
    """
    try:
        from osgeo import gdal, osr
    except ImportError:  # pragma: no cover (QGIS's Python ships GDAL's bindings)
        return fallback
    path = "/vsimem/rayscan_crs_{}.tif".format(uuid.uuid4().hex)
    try:
        srs = osr.SpatialReference()
        if srs.ImportFromWkt(wkt) != 0:
            return fallback
        srs.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
        ds = gdal.GetDriverByName("GTiff").Create(path, 1, 1, 1, gdal.GDT_Float32)
        if ds is None:
            return fallback
        ds.SetGeoTransform([0.0, 1.0, 0.0, 0.0, 0.0, -1.0])
        ds.SetSpatialRef(srs)
        ds = None  # written on close
        layer = QgsRasterLayer(path, "crs", "gdal")
        crs = layer.crs() if layer.isValid() else QgsCoordinateReferenceSystem()
        return crs if crs.isValid() else fallback
    except RuntimeError:  # GDAL's failures where gdal.UseExceptions() is in force
        return fallback
    finally:
        if gdal.VSIStatL(path) is not None:
            gdal.Unlink(path)
