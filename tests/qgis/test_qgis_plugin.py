#!/usr/bin/env python3
"""The QGIS Processing plugin (qgis/rayscan_processing) under Debian's headless qgis_process.

Checks: the progress parser, cancellation and refusals of runner.py against a stand-in executable;
the plugin enabled in a throwaway profile; `qgis_process list` shows the five rayscan algorithms;
`qgis_process run rayscan:viewshed` writes the same GeoTIFF as `rayscan visibility` (cell for cell,
also with observers in EPSG:4326 that the plugin reprojects, and without a CRS, with a warning);
ortho_dsm, solar and point_visibility outputs (its point vector layer too) open with the cloud's
CRS, the vector layer's CRS is the viewshed GeoTIFF's as QGIS reads them, quick_look's image opens,
ortho_dsm's COLOUR reaches the orthophoto; PRIMITIVE, ortho_dsm's COLOUR and solar's VALUE offer
the CLI's own values (its --help); the plugin's file extensions and filters are the ones rayscan's
refusals list (input clouds, per-point outputs, images, GeoTIFF maps); rayscan's refusals and the
plugin's own (an observer QGIS cannot reproject, a missing HEIGHT_FIELD, an observer outside the
cloud, a period without START and END) reach the user in one line naming the parameters and features, not the CLI's options or the
temporary CSV; a cancel while POINTS_LAYER is written leaves no file there; the progress parser
reads the progress lines of the real rayscan; viewshed's PRIMITIVE reaches rayscan; the log names
HEIGHT's unit; in this process, POINTS_LAYER "" makes no layer, the 0/1 maps loaded into a project
get their two classes, and no observer CSV is left behind. Exit 77 (skipped) when qgis_process is
not installed.

Usage: test_qgis_plugin.py RAYSCAN PLUGIN_DIR PLUGIN_ZIP CLOUD WORK_DIR
PLUGIN_DIR holds the build's copy rayscan_processing/ (the in-process checks import it); qgis_process
loads the plugin from PLUGIN_ZIP extracted as QGIS's "Install from ZIP" does, after checking that
the zip holds the build's copy file for file.
"""

import json
import os
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import time
import zipfile

ALGORITHMS = ["quick_look", "ortho_dsm", "viewshed", "point_visibility", "solar"]
# Autzen is in international feet: an eye 6 ft above the ground on open ground, 3-ft cells (docs/visibility.md).
OBSERVER = (636226.5, 849106.5)
HEIGHT = 6
CELL = 3
failures = []
keep_alive = []


def check(ok, what):
    """Record one check; print it either way."""
    print(("ok    " if ok else "FAIL  ") + what, flush=True)
    if not ok:
        failures.append(what)


def qgis_process_command():
    """Debian's qgis_process, or None when it is not installed.

    Debian 12's /usr/bin/qgis_process wrapper passes --noversioncheck (from /etc/default/qgis),
    which qgis_process 3.22 rejects ("Command --noversioncheck not known!"); the program the
    wrapper execs, qgis_process.bin, is run directly where it exists.
    """
    for name in ("qgis_process.bin", "qgis_process"):
        path = shutil.which(name)
        if path:
            return path
    return None


def unit_tests(plugin_dir, work):
    """The progress parser and run_rayscan's progress, failure and cancellation, in this interpreter."""
    sys.dont_write_bytecode = True  # no __pycache__ in the build tree's plugin copy
    sys.path.insert(0, plugin_dir)
    from rayscan_processing.cli_progress import parse_progress
    check(parse_progress("progress: 12/215 chunks   5.6%  341999 points/s  ETA 3 s") == 5.6, "progress line")
    check(parse_progress("progress: 215/215 chunks 100.0%  341999 points/s  done in 0 s") == 100.0, "last progress line")
    check(parse_progress("progress: 3/8 ray blocks  37.5%  2048 rays/s  ETA 1 s") == 37.5,
          "progress line whose items are two words")
    check(parse_progress("index: sort  42.0%  4200000 / 10000000 points  3.1 M points/s") == 42.0, "phase line")
    check(parse_progress("db import: insert  100.0%  110000 / 110000 points") == 100.0, "two-word command phase line")
    check(parse_progress("rayscan visibility: line of sight: 110000 points; 29116 points (26.5 %) seen") is None,
          "a log line with a percentage is not progress")
    check(parse_progress("wrote /tmp/a.tif") is None, "other lines are not progress")

    from qgis.core import QgsProcessingException
    from rayscan_processing import runner

    class Feedback:
        """The part of QgsProcessingFeedback runner.py uses; cancels once progress reaches cancel_at."""

        def __init__(self, cancel_at=None):
            self.progress, self.log, self.cancel_at = [], [], cancel_at

        def isCanceled(self):  # noqa: N802
            return self.cancel_at is not None and any(p >= self.cancel_at for p in self.progress)

        def setProgress(self, p):  # noqa: N802
            self.progress.append(p)

        def pushConsoleInfo(self, line):  # noqa: N802
            self.log.append(line)

        pushCommandInfo = pushConsoleInfo
        pushWarning = pushConsoleInfo

    # A stand-in executable: progress lines as rayscan writes them into a pipe, then a long sleep
    # that only a cancellation ends early; exit status from its first argument.
    fake = os.path.join(work, "fake-rayscan")
    with open(fake, "w") as f:
        f.write("#!/bin/sh\necho 'fake: starting' >&2\n"
                "for i in 1 2 3; do echo \"progress: $i/4 chunks  $((i * 25)).0%  10 points/s  ETA 1 s\" >&2; done\n"
                "echo result\n"
                "[ \"$1\" = fail ] && { echo 'fake: broken' >&2; exit 3; }\n"
                "[ \"$1\" = refuse ] && { echo \"$2\" >&2; exit 2; }\n"
                "[ \"$1\" = slow ] && exec sleep 60\nexit 0\n")
    os.chmod(fake, os.stat(fake).st_mode | stat.S_IXUSR)
    saved = os.environ.get("RAYSCAN_EXECUTABLE")
    os.environ["RAYSCAN_EXECUTABLE"] = fake
    try:
        fb = Feedback()
        out = runner.run_rayscan(["ok"], fb)
        check(fb.progress == [25.0, 50.0, 75.0] and out == "result" and "fake: starting" in fb.log,
              "run_rayscan: progress {} and standard output {!r}".format(fb.progress, out))
        try:
            runner.run_rayscan(["fail"], Feedback())
            check(False, "run_rayscan raises on a non-zero exit")
        except QgsProcessingException as e:
            check("status 3" in str(e) and "fake: broken" in str(e), "run_rayscan raises on a non-zero exit: " + str(e).splitlines()[0])
        # A refusal (exit 2) names the parameters that the labels give for the options' spellings:
        # rayscan names an option as it was given (--lat, -o), one not given by one of its spellings.
        labels = {"--lat": "Latitude [LATITUDE]", "--latitude": "Latitude [LATITUDE]", "-o": "Points [POINTS]",
                  "--out": "Points [POINTS]"}
        for line, expected in [
                ("rayscan solar: --lat: expected a finite number in [-90, 90], got '95' (see --help)",
                 "rayscan solar: Latitude [LATITUDE]: expected a finite number in [-90, 90], got '95'"),
                ("rayscan solar: --latitude and --longitude go together",
                 "rayscan solar: Latitude [LATITUDE] and --longitude go together"),
                ("rayscan solar: --out 'x--lat-o.foo': expected a file name ending in .las",
                 "rayscan solar: Points [POINTS] 'x--lat-o.foo': expected a file name ending in .las")]:
            fb = Feedback()
            try:
                runner.run_rayscan(["refuse", line], fb, labels=labels)
                got = None
            except QgsProcessingException as e:
                got = str(e)
            # The log has the refusal line in the same terms (its lines from two pipes, in either order).
            check(got == expected and expected in fb.log and line not in fb.log,
                  "run_rayscan: refusal {!r} reads {!r}, in the log too".format(line, got))
        # Cancellation: the child (the fake's `exec sleep 60`) is ended by a signal, which a child that
        # ran its course would not show (it exits 0), and run_rayscan has reaped it (returncode set).
        started, real_popen = [], subprocess.Popen

        class RecordingPopen(real_popen):
            def __init__(self, *args, **kwargs):
                super().__init__(*args, **kwargs)
                started.append(self)

        runner.subprocess.Popen = RecordingPopen
        try:
            runner.run_rayscan(["slow"], Feedback(cancel_at=50.0))
            check(False, "cancellation raises")
        except QgsProcessingException as e:
            codes = [p.returncode for p in started]
            check("canceled" in str(e) and codes in ([-signal.SIGTERM], [-signal.SIGKILL]),
                  "cancellation raises {!r} and ends the process by a signal (return codes {})".format(str(e), codes))
        finally:
            runner.subprocess.Popen = real_popen
        os.environ["RAYSCAN_EXECUTABLE"] = os.path.join(work, "does-not-exist")
        try:
            runner.find_executable()
            check(False, "a missing executable raises")
        except QgsProcessingException as e:
            check("RAYSCAN_EXECUTABLE" in str(e), "a missing executable raises: " + str(e))
    finally:
        if saved is None:
            os.environ.pop("RAYSCAN_EXECUTABLE", None)
        else:
            os.environ["RAYSCAN_EXECUTABLE"] = saved


def progress_checks(rayscan, cloud, work):
    """parse_progress on the lines the real rayscan writes into a pipe (render, visibility, solar,
    index, translate): each progress line, told by its own counts (base/src/progress.cpp's
    "progress: DONE/TOTAL ITEM", tools/phase_progress.cpp's "COMMAND: PHASE ... DONE / TOTAL
    points"), parses to 100 x DONE / TOTAL as printed (to its one decimal); every other line to None."""
    import re
    from rayscan_processing.cli_progress import parse_progress
    observer = ["--observer", "{},{}".format(*OBSERVER), "--height", str(HEIGHT)]
    runs = [["render", cloud, "--out", "p.png", "--width", "32", "--spp", "1"],
            ["visibility", cloud] + observer + ["-o", "p.las"],
            ["visibility", cloud] + observer + ["--raster", "p.tif", "--cell", str(CELL), "--no-preview"],
            ["solar", cloud, "--at", "2026-06-21T13:00-07:00", "--raster", "s.tif", "--cell", str(CELL),
             "--no-preview"],
            ["index", cloud, "--out", "p.rsi"], ["translate", cloud, "p.laz"]]
    folder = os.path.join(work, "progress")
    os.makedirs(folder)
    lines = []
    for args in runs:
        r = subprocess.run([rayscan] + args, cwd=folder, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                           stderr=subprocess.PIPE, universal_newlines=True)
        check(r.returncode == 0, "rayscan {} runs for its progress lines".format(args[0]))
        lines += [(args[0], line) for line in r.stderr.splitlines()]
    wrong, kinds, count = [], set(), 0
    for command, line in lines:
        counts = (re.match(r"progress: (\d+)/(\d+) ", line)
                  or re.match(re.escape(command) + r": \S+ .* (\d+) / (\d+) points", line))
        expected = round(100.0 * int(counts.group(1)) / int(counts.group(2)), 1) if counts else None
        got = parse_progress(line)
        if (got is None) != (expected is None) or (got is not None and abs(got - expected) > 0.051):
            wrong.append((line, got))
        if expected is not None:
            count += 1
            item = re.match(r"progress: \S+ (.*?) +[\d.]+%", line)
            kinds.add(item.group(1) if item else command)
    # The kinds this must cover: one-word and several-word items, and phase lines.
    check(not wrong and {"chunks", "points (surfels)", "tiles", "index", "translate"} <= kinds,
          "parse_progress reads each of rayscan's {} progress lines (items {}) and no other of its {} "
          "lines: wrong {}".format(count, sorted(kinds), len(lines), wrong))


def cli_choices(rayscan, command, option):
    """The values `rayscan COMMAND --help` gives for OPTION: CLI11's {a,b} set and its =default (or
    None); else the words of the description's "a | b | c" lists, in order, each once, and None."""
    import re
    text = subprocess.check_output([rayscan, command, "--help"], universal_newlines=True)
    m = re.search(r"^\s*{} TEXT:\{{([^}}]*)\}}(?:=(\S+))?".format(re.escape(option)), text, re.M)
    if m:
        return m.group(1).split(","), m.group(2)
    m = re.search(r"^\s*{} TEXT\s+(.*)$".format(re.escape(option)), text, re.M)
    words = []
    for run in re.findall(r"\w+(?: \| \w+)+", m.group(1) if m else ""):
        words += [w for w in run.split(" | ") if w not in words]
    return words, None


def cli_extensions(rayscan, args):
    """The extensions rayscan lists when it refuses a file name: ``rayscan ARGS`` (which end in a
    name it refuses) exits with status 2 and its last line says "... ending in .a, .b or .c".
    """
    import re
    r = subprocess.run([rayscan] + args, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                       stderr=subprocess.PIPE, universal_newlines=True)
    line = r.stderr.strip().splitlines()[-1] if r.stderr.strip() else ""
    tail = line.split("ending in ", 1)[1] if r.returncode == 2 and "ending in " in line else ""
    return tuple(re.findall(r"\.[\w.]*\w", re.split(r"\)| \(", tail)[0]))


def extension_checks(rayscan, cloud, work):
    """The plugin's lists of file extensions (algorithms/base.py, copies: the parameters are declared
    before rayscan may be run) are the ones rayscan's own refusals list, and the plugin accepts
    each: input clouds (`rayscan info`, and the index file its --help names), per-point outputs
    (`rayscan visibility -o`), images (`rayscan render --out`) and GeoTIFF maps (`render --dsm`)."""
    from qgis.core import QgsProcessingException
    from rayscan_processing.algorithms import base
    wrong = os.path.join(work, "points.unknown")
    cli = {
        "CLOUD_EXTENSIONS": cli_extensions(rayscan, ["info", wrong]) + (".rsi",),
        "POINTS_EXTENSIONS": cli_extensions(rayscan, ["visibility", cloud, "--observer", "0,0,0", "-o", wrong]),
        "IMAGE_EXTENSIONS": cli_extensions(rayscan, ["render", cloud, "--out", wrong]),
        "GEOTIFF_EXTENSIONS": cli_extensions(rayscan, ["render", cloud, "--ortho-map", "1", "--dsm", wrong,
                                                       "--out", os.path.join(work, "o.tif")]),
    }
    info_help = subprocess.check_output([rayscan, "info", "--help"], universal_newlines=True)
    check("index file (.rsi)" in info_help, "rayscan info --help names the index file (.rsi)")
    for name, theirs in cli.items():
        ours = getattr(base, name)
        check(len(theirs) > 1 and ours == theirs, "plugin {} {} are rayscan's {}".format(name, ours, theirs))
        refused = []
        for e in ours:
            try:
                base.RayscanAlgorithm.check_extension("/data/a" + e.upper(), ours, name)
            except QgsProcessingException:
                refused.append(e)
        check(not refused, "plugin check_extension accepts each of {} (refused: {})".format(name, refused))
    filters = {"CLOUD_FILTER": base.CLOUD_EXTENSIONS, "POINTS_FILTER": base.POINTS_EXTENSIONS,
               "IMAGE_FILTER": base.IMAGE_EXTENSIONS}
    for name, exts in filters.items():
        missing = [e for e in exts if "*" + e not in getattr(base, name)]
        check(not missing, "plugin {} offers each extension (missing: {})".format(name, missing))


def desktop_checks(plugin_dir, cloud, work, rayscan):
    """The desktop's way in (classFactory, initGui, unload) with the Processing plugin: the provider,
    its executable option in Processing's settings, the parameters that mirror CLI options (each
    option table entry a parameter, PRIMITIVE and solar's VALUE the CLI's values), an algorithm run
    as the Python console runs it (processing.run) and as the batch dialog does
    (QgsProcessingAlgorithm.run), and the provider and option gone after unload."""
    from qgis.core import QgsApplication
    app = QgsApplication([], True)  # offscreen (QT_QPA_PLATFORM)
    app.initQgis()
    sys.path[:0] = [os.path.join(QgsApplication.pkgDataPath(), "python", "plugins"), plugin_dir]
    from processing.core.Processing import Processing
    from processing.core.ProcessingConfig import ProcessingConfig
    Processing.initialize()
    import rayscan_processing
    plugin = rayscan_processing.classFactory(None)
    plugin.initGui()
    registry = QgsApplication.processingRegistry()
    provider = registry.providerById("rayscan")
    ids = sorted(a.name() for a in provider.algorithms()) if provider else []
    check(ids == sorted(ALGORITHMS) and "RAYSCAN_EXECUTABLE" in ProcessingConfig.settings,
          "desktop: initGui registers the provider {} and its executable option".format(ids))
    viewshed = registry.algorithmById("rayscan:viewshed")
    types = {d.name(): d.type() for d in viewshed.parameterDefinitions()} if viewshed else {}
    check(types.get("INPUT") == "file" and types.get("OBSERVERS") == "source"
          and types.get("OUTPUT") == "rasterDestination",
          "desktop: viewshed's parameter types {}".format(types))
    algs = {a: registry.createAlgorithmById("rayscan:" + a) for a in ALGORITHMS}
    for a, alg in algs.items():
        missing = [n for n in alg.FLAGS if alg.parameterDefinition(n) is None]
        check(alg.FLAGS and not missing, "desktop: {}'s option table names its parameters (missing: {})".format(a, missing))
    # PRIMITIVE: one numbering everywhere, the CLI's values, and each algorithm's default the CLI's.
    for a, command in (("quick_look", "render"), ("viewshed", "visibility"), ("point_visibility", "visibility"),
                       ("solar", "solar")):
        d = algs[a].parameterDefinition("PRIMITIVE")
        values, default = cli_choices(rayscan, command, "--primitive")
        options = d.options() if d else []
        check(options == ["surfel", "sphere"] and sorted(options) == sorted(values)
              and (default is None or options[d.defaultValue()] == default),
              "desktop: {}'s PRIMITIVE {} (default {}) has rayscan {} --primitive's values {} (default {})".format(
                  a, options, d.defaultValue() if d else None, command, values, default))
    d = algs["ortho_dsm"].parameterDefinition("COLOUR")
    values, default = cli_choices(rayscan, "render", "--ortho-colour")
    check(d is not None and d.type() == "enum" and d.options() == values and default is not None
          and d.options()[d.defaultValue()] == default,
          "desktop: ortho_dsm's COLOUR {} is rayscan render --ortho-colour's {} (default {})".format(
              d.options() if d else None, values, default))
    d = algs["solar"].parameterDefinition("VALUE")
    values, _ = cli_choices(rayscan, "solar", "--raster-value")
    check(d is not None and d.type() == "enum" and d.options()[1:] == values and d.defaultValue() == 0,
          "desktop: solar's VALUE is 'default' then rayscan solar --raster-value's {}: {}".format(
              values, d.options() if d else None))
    import processing
    from qgis.core import QgsProcessingContext, QgsProcessingFeedback
    from osgeo import gdal
    for how, output, call in [
            ("processing.run", "console.tif",
             lambda p: processing.run("rayscan:quick_look", p)),
            ("QgsProcessingAlgorithm.run (the batch dialog)", "batch.png",
             lambda p: registry.createAlgorithmById("rayscan:quick_look").run(
                 p, QgsProcessingContext(), QgsProcessingFeedback()))]:
        path = os.path.join(work, output)
        try:
            call({"INPUT": cloud, "WIDTH": 64, "SPP": 1, "OUTPUT": path})
            raster = gdal.Open(path)
            ok, why = raster is not None and raster.RasterXSize == 64, "GDAL opened {}".format(raster is not None)
        except Exception as e:  # the check's subject: any exception is the failure it reports
            ok, why = False, "{}: {}".format(type(e).__name__, e)
        check(ok, "desktop: {} runs rayscan:quick_look to a 64-pixel {} ({})".format(how, output, why))
    plugin.unload()
    check(registry.providerById("rayscan") is None and "RAYSCAN_EXECUTABLE" not in ProcessingConfig.settings,
          "desktop: unload removes the provider and the option")
    return app


def cancel_copy_check(plugin_dir, cloud, observers, work):
    """A cancel while point_visibility copies the points into POINTS_LAYER leaves no file at that
    path (no GeoPackage without its table, no -journal), as rayscan leaves no partial output; the
    cloud rayscan completed before stays. Run in this process (processing.run), canceling as the
    plugin announces the copy, so no timing is involved."""
    import processing
    import rayscan_processing
    from qgis.core import QgsProcessingException, QgsProcessingFeedback

    class CancelOnCopy(QgsProcessingFeedback):
        """Cancels when the copy into the vector layer begins."""

        def pushInfo(self, text):  # noqa: N802 (QGIS's name)
            if text.startswith("Writing "):
                self.cancel()
            super().pushInfo(text)

    plugin = rayscan_processing.classFactory(None)
    plugin.initProcessing()
    folder = os.path.join(work, "cancel_copy")
    os.makedirs(folder)
    try:
        processing.run("rayscan:point_visibility", {
            "INPUT": cloud, "OBSERVERS": observers, "HEIGHT": HEIGHT, "OUTPUT": os.path.join(folder, "pv.las"),
            "POINTS_LAYER": os.path.join(folder, "pv.gpkg")}, feedback=CancelOnCopy())
        error = None
    except QgsProcessingException as e:
        error = str(e)
    finally:
        plugin.unload()
    left = sorted(os.listdir(folder))
    check(error is not None and "Canceled while writing" in error and left == ["pv.las"],
          "point_visibility canceled while writing POINTS_LAYER: {!r}; the folder holds {}".format(error, left))


def in_process_checks(cloud, observers, far, unprojectable, work):
    """What a run in QGIS itself gives beyond qgis_process's output, run in this process as the
    dialog and the console run algorithms: POINTS_LAYER given as "" makes no vector layer and no
    error; a 0/1 raster loaded into the project (viewshed's viewshed and viewshed-points, solar's
    in_shadow) has two named classes once Processing's own loading step (handleAlgorithmResults)
    has run, every cell of it in one, while other values keep QGIS's default style; the eye
    height's note names the CRS's unit (GDAL's linear unit the oracle), warning where it is not
    metres; and no observer CSV is left in Processing's temporary folder by any run of this
    process, completed, refused by rayscan, refused by the plugin or canceled (cancel_copy_check)."""
    import processing
    import rayscan_processing
    from osgeo import osr
    from processing.gui.Postprocessing import handleAlgorithmResults
    from qgis.core import (QgsApplication, QgsCoordinateReferenceSystem, QgsProcessingContext,
                           QgsProcessingException, QgsProcessingFeedback, QgsProcessingOutputLayerDefinition,
                           QgsProcessingUtils, QgsProject)
    from rayscan_processing.algorithms import observers as observer_module

    plugin = rayscan_processing.classFactory(None)
    plugin.initProcessing()
    registry = QgsApplication.processingRegistry()
    folder = os.path.join(work, "in_process")
    os.makedirs(folder)
    try:
        out = os.path.join(folder, "pv.las")
        try:
            results = processing.run("rayscan:point_visibility", {
                "INPUT": cloud, "OBSERVERS": observers, "HEIGHT": HEIGHT, "OUTPUT": out, "POINTS_LAYER": ""})
            ok, why = "POINTS_LAYER" not in results, "results {}".format(sorted(results))
        except QgsProcessingException as e:
            ok, why = False, str(e)
        check(ok and sorted(os.listdir(folder)) == ["pv.las"],
              "point_visibility with POINTS_LAYER '' runs without the vector layer ({}; the folder holds {})".format(
                  why, sorted(os.listdir(folder))))

        def loaded(alg_id, params, output):
            """Run ``alg_id`` as the dialog does with "Open output file after running" (``output``
            an output definition into the project, then Processing's loading step); return the
            renderer of the layer it loaded (None when none) and the raster's values."""
            project = QgsProject.instance()
            context = QgsProcessingContext()
            context.setProject(project)
            feedback = QgsProcessingFeedback()
            path = os.path.join(folder, params[output])
            params = dict(params, **{output: QgsProcessingOutputLayerDefinition(path, project)})
            alg = registry.createAlgorithmById(alg_id)
            _, ok = alg.run(params, context, feedback)
            if ok:
                handleAlgorithmResults(alg, context, feedback, False, params)
            layers = [layer for layer in project.mapLayers().values() if os.path.abspath(layer.source()) == path]
            renderer = layers[0].renderer().clone() if layers else None
            project.removeAllMapLayers()
            r = read_raster(path) if ok else None
            return renderer, sorted(set(r[0][r[0] != r[3]].tolist())) if r else None

        viewshed = {"INPUT": cloud, "OBSERVERS": observers, "HEIGHT": HEIGHT, "CELL": CELL}
        for alg_id, params, output, classes in [
                ("rayscan:viewshed", dict(viewshed, OUTPUT="seen.tif"), "OUTPUT", [(0, "not seen"), (1, "seen")]),
                ("rayscan:viewshed", dict(viewshed, VALUE=2, OUTPUT="seen_points.tif"), "OUTPUT",
                 [(0, "not seen"), (1, "seen")]),
                ("rayscan:viewshed", dict(viewshed, VALUE=1, OUTPUT="count.tif"), "OUTPUT", None),
                ("rayscan:solar", {"INPUT": cloud, "MODE": 1, "AT": "2026-06-21T13:00-07:00", "CELL": CELL,
                                   "OUTPUT": "shadow.tif"}, "OUTPUT", [(0, "sun"), (1, "shadow")])]:
            renderer, values = loaded(alg_id, params, output)
            got = ([(c.value, c.label) for c in renderer.classes()] if renderer is not None
                   and renderer.type() == "paletted" else renderer.type() if renderer is not None else None)
            if classes is None:
                ok = renderer is not None and renderer.type() != "paletted"
            else:
                ok = got == classes and values is not None and set(values) <= {v for v, _ in classes}
            check(ok, "{} {} loaded into the project: style {} (expected {}), values {}".format(
                alg_id, params[output], got, classes or "QGIS's default", values))

        alg = registry.createAlgorithmById("rayscan:viewshed")
        for epsg, warn in (("EPSG:32610", False), ("EPSG:2994", True), ("EPSG:2264", True)):
            srs = osr.SpatialReference()
            srs.ImportFromEPSG(int(epsg.split(":")[1]))
            metres = "= {:.3g} m".format(1.7 * srs.GetLinearUnits())
            got = observer_module.eye_height_note(alg, QgsCoordinateReferenceSystem(epsg), 1.7, "")
            check(got[0] == warn and (metres in got[1] if warn else "meters" in got[1]),
                  "the eye height 1.7 in {} ({}, {} m): {} (warning: {})".format(
                      epsg, srs.GetLinearUnitsName(), srs.GetLinearUnits(), got[1], got[0]))

        for alg_id, params, what in [
                ("rayscan:viewshed", dict(viewshed, OBSERVERS=far, OUTPUT=os.path.join(folder, "far.tif")),
                 "refused by rayscan"),
                ("rayscan:point_visibility", {"INPUT": cloud, "OBSERVERS": unprojectable,
                                              "OUTPUT": os.path.join(folder, "bad.las")}, "refused by the plugin")]:
            try:
                processing.run(alg_id, params)
                check(False, "{}: {}".format(alg_id, what))
            except QgsProcessingException:
                pass
    finally:
        plugin.unload()
    left = [os.path.join(d, f) for d, _, fs in os.walk(QgsProcessingUtils.tempFolder()) for f in fs
            if f == "observers.csv"]
    check(not left, "no observer CSV left in Processing's temporary folder {}: {}".format(
        QgsProcessingUtils.tempFolder(), left))


def read_raster(path):
    """(array, geotransform, srs, nodata) of a single-band raster, or None when GDAL cannot open it."""
    from osgeo import gdal, osr
    ds = gdal.Open(path)
    if ds is None:
        return None
    srs = osr.SpatialReference()
    if ds.GetProjection():
        srs.ImportFromWkt(ds.GetProjection())
    band = ds.GetRasterBand(1)
    return ds.ReadAsArray(), ds.GetGeoTransform(), srs, band.GetNoDataValue()


def main():
    """Run the checks; the exit status is the number of failures (77: skipped)."""
    rayscan, plugin_dir, plugin_zip, cloud, work = (os.path.abspath(a) for a in sys.argv[1:6])
    qgis_process = qgis_process_command()
    if qgis_process is None:
        print("SKIP: qgis_process is not installed (Debian package qgis; tools/install-deps.sh)")
        return 77
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    # The zip: one top folder rayscan_processing/ with the build's copy, byte for byte.
    installed = os.path.join(work, "plugins")
    with zipfile.ZipFile(plugin_zip) as z:
        names = sorted(n for n in z.namelist() if not n.endswith("/"))
        z.extractall(installed)
    copy = sorted(os.path.relpath(os.path.join(d, f), plugin_dir).replace(os.sep, "/")
                  for d, _, fs in os.walk(os.path.join(plugin_dir, "rayscan_processing"))
                  for f in fs if "__pycache__" not in d)
    same = names == copy and all(open(os.path.join(installed, n), "rb").read() ==
                                 open(os.path.join(plugin_dir, n), "rb").read() for n in names)
    check(same, "the zip {} holds the build's plugin copy ({} files under rayscan_processing/)".format(
        os.path.basename(plugin_zip), len(names)))
    home = tempfile.mkdtemp(prefix="home-", dir=work)
    # A throwaway profile and headless Qt: the user's QGIS settings are never read or written.
    env = dict(os.environ, HOME=home, XDG_CONFIG_HOME=os.path.join(home, ".config"),
               XDG_DATA_HOME=os.path.join(home, ".local", "share"),
               XDG_CACHE_HOME=os.path.join(home, ".cache"), XDG_RUNTIME_DIR=home,
               QT_QPA_PLATFORM="offscreen", QGIS_PLUGINPATH=installed,
               PYTHONDONTWRITEBYTECODE="1", RAYSCAN_EXECUTABLE=rayscan)
    os.environ.update(env)

    def qp(*args):
        """Run qgis_process ARGS; return (exit status, output), the output echoed.

        Of a successful `list` only the rayscan provider's lines are echoed (QGIS's own run to hundreds).
        """
        t0 = time.monotonic()
        r = subprocess.run([qgis_process] + list(args), env=env, stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, universal_newlines=True)
        shown = r.stdout
        if args[0] == "list" and r.returncode == 0:
            shown = "".join(line + "\n" for line in r.stdout.splitlines()
                            if line.startswith("rayscan") or "rayscan:" in line)
        print("$ qgis_process {}  ({:.1f} s, exit {})\n{}".format(
            subprocess.list2cmdline(args), time.monotonic() - t0, r.returncode, shown), flush=True)
        return r.returncode, r.stdout

    unit_tests(plugin_dir, work)
    progress_checks(rayscan, cloud, work)
    extension_checks(rayscan, cloud, work)
    keep_alive.append(desktop_checks(plugin_dir, cloud, work, rayscan))  # the QgsApplication, for the transforms below

    code, _ = qp("plugins", "enable", "rayscan_processing")
    check(code == 0, "qgis_process plugins enable rayscan_processing")
    code, out = qp("list")
    check(code == 0 and all("rayscan:" + a in out for a in ALGORITHMS),
          "qgis_process list shows rayscan:" + ", rayscan:".join(ALGORITHMS))

    from osgeo import ogr, osr
    info = json.loads(subprocess.check_output([rayscan, "info", "--json", cloud]))
    cloud_srs = osr.SpatialReference()
    cloud_srs.ImportFromWkt(info["crs"]["wkt2"])

    # The observer as a GeoPackage point layer in the cloud's CRS, made as docs/qgis.md makes it:
    # a CSV, and the cloud's WKT from `rayscan info --json` given to ogr2ogr.
    csv_path, wkt_path, gpkg = (os.path.join(work, n) for n in ("observer.csv", "autzen.wkt", "observer.gpkg"))
    with open(csv_path, "w") as f:
        f.write("x,y,name\n{},{},west\n".format(*OBSERVER))
    with open(wkt_path, "w") as f:
        f.write(info["crs"]["wkt2"] + "\n")
    subprocess.check_call(["ogr2ogr", "-f", "GPKG", gpkg, csv_path, "-oo", "X_POSSIBLE_NAMES=x",
                           "-oo", "Y_POSSIBLE_NAMES=y", "-a_srs", wkt_path, "-nln", "observer"])

    def cli_viewshed(name, x, y, extra=()):
        """The CLI's viewshed from the observer at (x, y) (as given: repr round-trips a double), HEIGHT
        above ground, with the options ``extra``."""
        path = os.path.join(work, name)
        subprocess.check_call([rayscan, "visibility", cloud, "--observer", "{!r},{!r}".format(x, y),
                               "--height", str(HEIGHT), "--raster", path, "--cell", str(CELL), "-q", *extra])
        return path, read_raster(path)

    cli_tif, cli = cli_viewshed("cli_viewshed.tif", *OBSERVER)

    def same_viewshed(observers, extra, what, expect=(), reference=(cli_tif, cli)):
        """Run rayscan:viewshed; check its GeoTIFF against the CLI's (``reference``: its path and
        read_raster), and its output for each text of ``expect``; return the plugin's GeoTIFF."""
        ref_tif, ref = reference
        out_tif = os.path.join(work, "qgis_viewshed_{}.tif".format(len(os.listdir(work))))
        code, out = qp("run", "rayscan:viewshed", "--", "INPUT=" + cloud, "OBSERVERS=" + observers,
                     "CELL={}".format(CELL), "OUTPUT=" + out_tif, *extra)
        got = read_raster(out_tif) if code == 0 else None
        import numpy
        equal = (got is not None and got[0].shape == ref[0].shape and numpy.array_equal(got[0], ref[0])
                 and got[1] == ref[1] and got[3] == ref[3] and got[2].IsSame(ref[2]))
        detail = ""
        if got is not None and got[0].shape == ref[0].shape:
            detail = "{} of {} cells differ".format(int((got[0] != ref[0]).sum()), ref[0].size)
        check(equal and all(w in out for w in expect), "{}: same GeoTIFF as rayscan visibility, cell for cell ({}x{} cells, {}; {} visible, {} NoData; "
              "files byte-identical: {})".format(what, ref[0].shape[1], ref[0].shape[0], detail or "unreadable",
                                                int((ref[0] == 1).sum()), int((ref[0] == ref[3]).sum()),
                                                got is not None and open(out_tif, "rb").read() == open(ref_tif, "rb").read()))
        return out_tif

    # HEIGHT is in the cloud's unit, which the log names, with a warning where it is not metres
    # (autzen: international feet, its WKT's linear unit as GDAL reads it).
    feet = "{:g} feet = {:.3g} m".format(HEIGHT, HEIGHT * cloud_srs.GetLinearUnits())
    plugin_tif = same_viewshed(gpkg, ["HEIGHT={}".format(HEIGHT)], "viewshed, observer in the cloud's CRS, "
                               "warning that HEIGHT is {}".format(feet),
                               expect=("WARNING:\tEye height above the local ground (cloud units) [HEIGHT] {:g} is "
                                       "in feet".format(HEIGHT), feet))

    # PRIMITIVE reaches rayscan: viewshed-points (VALUE 2) over spheres, which see under the crowns
    # where surfels are solid, is the CLI's with --primitive sphere, not its default surfel map.
    points_value = ["--raster-value", "viewshed-points"]
    sphere = cli_viewshed("cli_points_sphere.tif", *OBSERVER, extra=points_value + ["--primitive", "sphere"])
    surfel = cli_viewshed("cli_points_surfel.tif", *OBSERVER, extra=points_value)
    differ = int((sphere[1][0] != surfel[1][0]).sum())
    check(differ > 0, "viewshed-points: spheres and surfels differ in {} cells".format(differ))
    same_viewshed(gpkg, ["HEIGHT={}".format(HEIGHT), "VALUE=2", "PRIMITIVE=1"],
                  "viewshed, viewshed-points with PRIMITIVE=1 (sphere)", expect=("--primitive sphere",),
                  reference=sphere)

    # The same eye as an absolute Z (the CLI's resolved eye: ground 427.85 ft + 6 ft).
    csv_z, gpkg_z = os.path.join(work, "observer_z.csv"), os.path.join(work, "observer_z.gpkg")
    with open(csv_z, "w") as f:
        f.write("x,y,z,name\n{},{},433.85,west\n".format(*OBSERVER))
    subprocess.check_call(["ogr2ogr", "-f", "GPKG", gpkg_z, csv_z, "-oo", "X_POSSIBLE_NAMES=x",
                           "-oo", "Y_POSSIBLE_NAMES=y", "-oo", "Z_POSSIBLE_NAMES=z", "-a_srs", wkt_path,
                           "-nln", "observer"])
    same_viewshed(gpkg_z, ["USE_Z=true"], "viewshed, observer's Z as the absolute eye")

    # The same observer in EPSG:4326 (GeoJSON), its height from a field. The plugin reprojects it
    # to the CRS QGIS reads from rayscan's GeoTIFFs, so the eye lands where QGIS draws it over the
    # viewshed; the round trip through degrees moves it by nanometres, which can flip a cell, so
    # the reference is the CLI at the coordinates that QGIS's transform gives back.
    from qgis.core import (QgsCoordinateReferenceSystem, QgsCoordinateTransform,
                           QgsCoordinateTransformContext, QgsPointXY, QgsRasterLayer, QgsVectorLayer)
    raster_crs = QgsRasterLayer(cli_tif, "cli", "gdal").crs()
    wgs84 = QgsCoordinateReferenceSystem("EPSG:4326")
    lonlat = QgsCoordinateTransform(raster_crs, wgs84, QgsCoordinateTransformContext()).transform(QgsPointXY(*OBSERVER))
    geojson = os.path.join(work, "observer_wgs84.geojson")
    with open(geojson, "w") as f:
        json.dump({"type": "FeatureCollection", "features": [{
            "type": "Feature", "properties": {"eye": HEIGHT},
            "geometry": {"type": "Point", "coordinates": [lonlat.x(), lonlat.y()]}}]}, f)
    back = QgsCoordinateTransform(wgs84, raster_crs, QgsCoordinateTransformContext()).transform(lonlat)
    same_viewshed(geojson, ["HEIGHT=1", "HEIGHT_FIELD=eye"],
                  "viewshed, observer in EPSG:4326 reprojected to ({!r}, {!r}), height from a field".format(
                      back.x(), back.y()),
                  expect=("Observers reprojected from EPSG:4326 - WGS 84 to the cloud's CRS "
                          + raster_crs.userFriendlyIdentifier(),),
                  reference=cli_viewshed("cli_viewshed_wgs84.tif", back.x(), back.y()))

    # The observer in the cloud's coordinates in a shapefile without a .prj: no CRS. It is taken
    # to be in the cloud's CRS, as QGIS's own algorithms take an unknown CRS, and the log says so.
    shp = os.path.join(work, "observer_nocrs.shp")
    subprocess.check_call(["ogr2ogr", "-f", "ESRI Shapefile", shp, csv_path, "-oo", "X_POSSIBLE_NAMES=x",
                           "-oo", "Y_POSSIBLE_NAMES=y"])
    check(not os.path.exists(shp[:-4] + ".prj"), "the shapefile observer_nocrs has no .prj")
    same_viewshed(shp, ["HEIGHT={}".format(HEIGHT)], "viewshed, observer layer without a CRS (warned)",
                  expect=("WARNING:\tObserver layer 'observer_nocrs' has no CRS: its coordinates are taken to "
                          "be in the cloud's CRS",))

    ortho, dsm = os.path.join(work, "ortho.tif"), os.path.join(work, "dsm.tif")
    code, _ = qp("run", "rayscan:ortho_dsm", "--", "INPUT=" + cloud, "CELL={}".format(CELL), "SPP=2",
                 "ORTHO=" + ortho, "DSM=" + dsm)
    for name, path in (("ortho", ortho), ("DSM", dsm)):
        r = read_raster(path) if code == 0 else None
        check(r is not None and r[2].IsSame(cloud_srs) and r[1][1] == CELL,
              "ortho_dsm: GDAL opens the {} with the cloud's CRS and {}-unit cells".format(name, CELL))
    r_dsm = read_raster(dsm) if code == 0 else None
    check(r_dsm is not None and r_dsm[0].shape == cli[0].shape and r_dsm[1] == cli[1],
          "ortho_dsm: the DSM has the viewshed's grid")
    from osgeo import gdal
    shaded = os.path.join(work, "ortho_shaded.tif")
    code_shaded, _ = qp("run", "rayscan:ortho_dsm", "--", "INPUT=" + cloud, "CELL={}".format(CELL), "COLOUR=1",
                        "SPP=2", "ORTHO=" + shaded, "DSM=" + os.path.join(work, "dsm_shaded.tif"))
    kinds = [gdal.Open(f).GetMetadataItem("RAYSCAN_ORTHO_COLOUR") if c == 0 and gdal.Open(f) else None
             for f, c in ((ortho, code), (shaded, code_shaded))]
    check(kinds == ["albedo", "shaded"], "ortho_dsm: the orthophoto's colour is albedo by default, shaded with "
          "COLOUR=1 (RAYSCAN_ORTHO_COLOUR: {})".format(kinds))

    quick = os.path.join(work, "quick.png")
    code, _ = qp("run", "rayscan:quick_look", "--", "INPUT=" + cloud, "WIDTH=240", "SPP=2", "OUTPUT=" + quick)
    r = read_raster(quick) if code == 0 else None
    # A perspective view has no map coordinates, so no CRS is expected.
    check(r is not None and r[0].shape[-1] == 240, "quick_look: GDAL opens the 240-pixel-wide image")

    solar_tif, solar_las = os.path.join(work, "shadow.tif"), os.path.join(work, "shadow.las")
    code, _ = qp("run", "rayscan:solar", "--", "INPUT=" + cloud, "MODE=1", "AT=2026-06-21T13:00-07:00",
                 "CELL={}".format(CELL), "OUTPUT=" + solar_tif, "POINTS=" + solar_las)
    r = read_raster(solar_tif) if code == 0 else None
    check(r is not None and r[2].IsSame(cloud_srs) and (r[0] != r[3]).any()
          and set(r[0][r[0] != r[3]].tolist()) <= {0.0, 1.0},
          "solar: shadow map (0/1) with the cloud's CRS")
    fields = json.loads(subprocess.check_output([rayscan, "info", "--json", solar_las])) if code == 0 else {}
    check("in_shadow" in json.dumps(fields.get("attributes", fields)), "solar: the cloud has the field in_shadow")

    # rayscan's refusals name the parameters: the solar job refuses a latitude without a longitude
    # (naming --lat as the plugin passed it, and --longitude) and an instant's map value that only a
    # period has. The command line in the log carries PRIMITIVE's value.
    refused = os.path.join(work, "refused.tif")
    raster_values, _ = cli_choices(rayscan, "solar", "--raster-value")
    for extra, command_has, error_has in [
            (["LATITUDE=45"], "--primitive sphere",
             "rayscan solar: Latitude (degrees; default from the CRS) [LATITUDE] and "
             "Longitude (degrees; default from the CRS) [LONGITUDE] go together"),
            (["VALUE={}".format(1 + raster_values.index("sun_hours")), "PRIMITIVE=0"], "--primitive surfel",
             "rayscan solar: Map value [VALUE] 'sun_hours': expected in_shadow, global, beam or diffuse")]:
        code, out = qp("run", "rayscan:solar", "--", "INPUT=" + cloud, "MODE=1", "AT=2026-06-21T13:00-07:00",
                       "CELL={}".format(CELL), "OUTPUT=" + refused, *extra)
        errors = [line for line in out.splitlines() if line.startswith("ERROR:")]
        commands = [line for line in out.splitlines() if line.startswith(rayscan + " solar ")]
        check(code != 0 and len(errors) == 1 and error_has in errors[0] and " -" not in errors[0]
              and len(commands) == 1 and command_has in commands[0] and not os.path.exists(refused),
              "solar {}: refused, naming the parameters: {}; command {}".format(" ".join(extra), errors, commands))

    pv, pv_layer = os.path.join(work, "visible.laz"), os.path.join(work, "visible.gpkg")
    code, _ = qp("run", "rayscan:point_visibility", "--", "INPUT=" + cloud, "OBSERVERS=" + gpkg,
                 "HEIGHT={}".format(HEIGHT), "DISTANCE=true", "OUTPUT=" + pv, "POINTS_LAYER=" + pv_layer)
    pinfo = json.loads(subprocess.check_output([rayscan, "info", "--json", "--stats", pv])) if code == 0 else {}
    stats = {a["name"]: a for a in pinfo.get("attributes", [])}
    check(pinfo.get("count") == info["count"] and "visible_count" in stats and "visible_distance" in stats,
          "point_visibility: {} points with visible_count and visible_distance".format(pinfo.get("count")))
    ds = ogr.Open(pv_layer) if code == 0 else None
    layer = ds.GetLayer(0) if ds else None
    seen = sum(f.GetField("visible_count") for f in layer) if layer else None
    expected = round(stats["visible_count"]["mean"] * pinfo["count"]) if "visible_count" in stats else None
    check(layer is not None and layer.GetFeatureCount() == info["count"] and seen == expected
          and layer.GetSpatialRef().IsSame(cloud_srs),
          "point_visibility: the point vector layer has every point, the cloud's CRS and the LAS's "
          "visible_count ({} points seen)".format(seen))
    layer = ds = None

    # Every layer of a run in one CRS, the one QGIS reads from rayscan's GeoTIFFs: the point layer
    # and the viewshed are equal CRS objects and a point goes to Web Mercator alike from both.
    vector_crs = QgsVectorLayer(pv_layer, "pv", "ogr").crs()
    viewshed_crs = QgsRasterLayer(plugin_tif, "viewshed", "gdal").crs()
    mercator = QgsCoordinateReferenceSystem("EPSG:3857")
    to_mercator = [QgsCoordinateTransform(c, mercator, QgsCoordinateTransformContext()).transform(QgsPointXY(*OBSERVER))
                   for c in (vector_crs, viewshed_crs)]
    check(vector_crs.isValid() and vector_crs == viewshed_crs == raster_crs
          and (to_mercator[0].x(), to_mercator[0].y()) == (to_mercator[1].x(), to_mercator[1].y()),
          "point_visibility's vector layer ({}) and viewshed's GeoTIFF ({}) have one CRS; the observer in "
          "EPSG:3857 from each: {}".format(vector_crs.userFriendlyIdentifier(), viewshed_crs.userFriendlyIdentifier(),
                                           [(p.x(), p.y()) for p in to_mercator]))

    def refused(alg, params, what, has, lacks=()):
        """Run rayscan:ALG; check it fails with one error line holding each text of ``has`` and none of
        ``lacks``, and no Python traceback; return its output."""
        code, out = qp("run", "rayscan:" + alg, "--", "INPUT=" + cloud, *params)
        errors = [line for line in out.splitlines() if line.startswith("ERROR:")]
        check(code != 0 and len(errors) == 1 and all(t in errors[0] for t in has)
              and not any(t in errors[0] for t in lacks) and "Traceback" not in out,
              "{}: refused in one line naming {}: {}".format(what, has, errors))
        return out

    # The autzen observer's feet labelled EPSG:4326: QGIS cannot take it to the cloud's CRS.
    csv_4326, gpkg_4326 = os.path.join(work, "observer_4326.csv"), os.path.join(work, "observer_4326.gpkg")
    with open(csv_4326, "w") as f:
        f.write("x,y\n{},{}\n".format(*OBSERVER))
    subprocess.check_call(["ogr2ogr", "-f", "GPKG", gpkg_4326, csv_4326, "-oo", "X_POSSIBLE_NAMES=x",
                           "-oo", "Y_POSSIBLE_NAMES=y", "-a_srs", "EPSG:4326", "-nln", "observer_4326"])
    for alg, output in (("viewshed", "bad.tif"), ("point_visibility", "bad.las")):
        refused(alg, ["OBSERVERS=" + gpkg_4326, "OUTPUT=" + os.path.join(work, output)],
                alg + ", an observer QGIS cannot reproject",
                ["Observers (points) [OBSERVERS] 'observer_4326', feature 1: ({!r}, {!r})".format(*OBSERVER),
                 "EPSG:4326 - WGS 84", raster_crs.userFriendlyIdentifier()])

    refused("viewshed", ["OBSERVERS=" + gpkg, "HEIGHT_FIELD=nosuch", "OUTPUT=" + os.path.join(work, "bad.tif")],
            "viewshed, a HEIGHT_FIELD the layer lacks",
            ["[HEIGHT_FIELD] 'nosuch' is not a field of Observers (points) [OBSERVERS] 'observer'; its numeric "
             "fields: fid, x, y"])

    # An observer beyond the cloud's west edge: rayscan's message names the feature, not the line of
    # the plugin's temporary CSV, and the parameter that widens the ground search. Features 1 and 2
    # are deleted, so the far one (feature 4) is the CSV's line 3, named '4'.
    csv_far, gpkg_far = os.path.join(work, "observer_far.csv"), os.path.join(work, "observer_far.gpkg")
    west = info["bounds"]["min"][0] - 100.0
    with open(csv_far, "w") as f:
        f.write("x,y\n{0},{1}\n{0},{1}\n{0},{1}\n{2},{1}\n".format(OBSERVER[0], OBSERVER[1], west))
    subprocess.check_call(["ogr2ogr", "-f", "GPKG", gpkg_far, csv_far, "-oo", "X_POSSIBLE_NAMES=x",
                           "-oo", "Y_POSSIBLE_NAMES=y", "-a_srs", wkt_path, "-nln", "observer_far"])
    subprocess.check_call(["ogrinfo", "-q", gpkg_far, "-sql", "DELETE FROM observer_far WHERE fid < 3"])
    far_tif = os.path.join(work, "far.tif")
    refused("viewshed", ["OBSERVERS=" + gpkg_far, "HEIGHT={}".format(HEIGHT), "CELL={}".format(CELL),
                         "OUTPUT=" + far_tif],
            "viewshed, an observer outside the cloud",
            ["rayscan visibility: Observers (points) [OBSERVERS] 'observer_far', feature 4: no point within the "
             "ground radius", "raise Local ground search radius (cloud units; empty = 5 x the point radius) "
             "[GROUND_RADIUS]"], lacks=["observers.csv", "line ", "--ground-radius"])
    code, out = qp("run", "rayscan:viewshed", "--", "INPUT=" + cloud, "OBSERVERS=" + gpkg_far,
                   "HEIGHT={}".format(HEIGHT), "CELL={}".format(CELL), "GROUND_RADIUS=200", "OUTPUT=" + far_tif)
    check(code == 0 and "--ground-radius 200.0" in out and read_raster(far_tif) is not None,
          "viewshed, GROUND_RADIUS=200 reaches rayscan as --ground-radius and places the far observer")

    refused("solar", ["CELL={}".format(CELL), "OUTPUT=" + os.path.join(work, "bad.tif")],
            "solar, a period without START and END",
            ["Mode [MODE] 'period (irradiation, kWh/m²)' needs Period start (ISO 8601, e.g. 2026-06-01) [START] "
             "and Period end (ISO 8601, e.g. 2026-06-30) [END]; START and END are empty"])

    cancel_copy_check(plugin_dir, cloud, gpkg, work)
    in_process_checks(cloud, gpkg, gpkg_far, gpkg_4326, work)

    print("{} failure(s)".format(len(failures)))
    for f in failures:
        print("  " + f)
    return min(len(failures), 70)


if __name__ == "__main__":
    sys.exit(main())
