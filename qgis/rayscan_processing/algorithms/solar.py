"""Solar: `rayscan solar CLOUD --start/--end or --at ... --raster MAP.tif --cell C [-o OUT.las]`."""

from qgis.core import (QgsProcessingException, QgsProcessingParameterDefinition,
                       QgsProcessingParameterEnum, QgsProcessingParameterFileDestination,
                       QgsProcessingParameterNumber, QgsProcessingParameterRasterDestination,
                       QgsProcessingParameterString)

from .base import POINTS_FILTER, RayscanAlgorithm

_MODES = ["period (irradiation, kWh/m²)", "instant (shadows)"]
_PRIMITIVES = ["sphere", "surfel"]


class Solar(RayscanAlgorithm):
    """Solar irradiation over a period, or shadows at an instant, as a top-surface GeoTIFF (and per point)."""

    NAME = "solar"
    DISPLAY = "Solar irradiation and shadows"
    HELP = ("Sun and shadow on the scanned site (rayscan solar), with the shadows the points cast on "
            "each other. Period: irradiation over START..END (ISO 8601; a date alone is local solar "
            "midnight, an end date includes that day) every STEP, clear sky as GRASS r.sun; the map "
            "value is global, beam, diffuse, reflected, sun_hours or sky_view (default global, kWh/m²). "
            "Instant: shadows at AT (ISO 8601, no offset = UTC); the map value is in_shadow (default), "
            "global, beam or diffuse (W/m²). The site's latitude and longitude come from the cloud's "
            "CRS unless given. The raster is the top surface seen from above, with the cloud's CRS; "
            "the optional cloud output carries every per-point field.")
    OUTPUT = "OUTPUT"
    POINTS = "POINTS"

    def initAlgorithm(self, config=None):  # noqa: N802 (QGIS's name)
        """Declare the parameters."""
        self.add_cloud_parameter()
        self.addParameter(QgsProcessingParameterEnum("MODE", self.tr("Mode"), _MODES, defaultValue=0))
        self.addParameter(QgsProcessingParameterString(
            "START", self.tr("Period start (ISO 8601, e.g. 2026-06-01)"), optional=True))
        self.addParameter(QgsProcessingParameterString(
            "END", self.tr("Period end (ISO 8601, e.g. 2026-06-30)"), optional=True))
        self.addParameter(QgsProcessingParameterString(
            "STEP", self.tr("Period time step (15min, 30min or 1h; at most 1h)"), defaultValue="1h"))
        self.addParameter(QgsProcessingParameterString(
            "AT", self.tr("Instant (ISO 8601, e.g. 2026-06-21T13:00-07:00)"), optional=True))
        self.addParameter(QgsProcessingParameterString(
            "VALUE", self.tr("Map value (empty: global for a period, in_shadow for an instant)"),
            optional=True))
        self.add_cell_parameter()
        advanced = [
            QgsProcessingParameterNumber("LATITUDE", self.tr("Latitude (degrees; default from the CRS)"),
                                         QgsProcessingParameterNumber.Double, None, True, -90.0, 90.0),
            QgsProcessingParameterNumber("LONGITUDE", self.tr("Longitude (degrees; default from the CRS)"),
                                         QgsProcessingParameterNumber.Double, None, True, -180.0, 180.0),
            QgsProcessingParameterNumber("LINKE", self.tr("Linke turbidity"),
                                         QgsProcessingParameterNumber.Double, 3.0, False, 1.0, 10.0),
            QgsProcessingParameterNumber("SECTOR", self.tr("Sun-map sector edge (degrees; 0 = one ray per step)"),
                                         QgsProcessingParameterNumber.Double, 1.0, False, 0.0, 30.0),
            QgsProcessingParameterEnum("PRIMITIVE", self.tr("Geometry that casts shadows"), _PRIMITIVES,
                                       defaultValue=0),
        ]
        for p in advanced:
            p.setFlags(p.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
            self.addParameter(p)
        self.addParameter(QgsProcessingParameterRasterDestination(self.OUTPUT, self.tr("Solar map")))
        self.addParameter(QgsProcessingParameterFileDestination(
            self.POINTS, self.tr("Cloud with solar fields"), POINTS_FILTER, optional=True,
            createByDefault=False))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 (QGIS's name)
        """Run rayscan solar and return the raster (and the cloud when asked)."""
        cloud = self.cloud(parameters, context)
        out = self.parameterAsOutputLayer(parameters, self.OUTPUT, context)
        self.check_extension(out, (".tif", ".tiff"), "The solar map")
        args = ["solar", cloud, "--raster", out, "--no-preview",
                "--cell", self.parameterAsDouble(parameters, "CELL", context),
                "--linke", self.parameterAsDouble(parameters, "LINKE", context),
                "--sector", self.parameterAsDouble(parameters, "SECTOR", context),
                "--primitive", _PRIMITIVES[self.parameterAsEnum(parameters, "PRIMITIVE", context)]]
        if self.parameterAsEnum(parameters, "MODE", context) == 0:
            start = self.parameterAsString(parameters, "START", context).strip()
            end = self.parameterAsString(parameters, "END", context).strip()
            if not start or not end:
                raise QgsProcessingException(self.tr("A period needs a start and an end"))
            args += ["--start", start, "--end", end,
                     "--step", self.parameterAsString(parameters, "STEP", context).strip() or "1h"]
        else:
            at = self.parameterAsString(parameters, "AT", context).strip()
            if not at:
                raise QgsProcessingException(self.tr("An instant needs a time (AT)"))
            args += ["--at", at]
        value = self.parameterAsString(parameters, "VALUE", context).strip()
        if value:
            args += ["--raster-value", value]
        for name, flag in (("LATITUDE", "--lat"), ("LONGITUDE", "--lon")):
            given = parameters.get(name)
            if given is not None and str(given) not in ("", "NULL"):
                args += [flag, self.parameterAsDouble(parameters, name, context)]
        points = self.parameterAsFileOutput(parameters, self.POINTS, context)
        if points:
            args += ["-o", points]
        self.run_cli(args, feedback)
        results = {self.OUTPUT: out}
        if points:
            results[self.POINTS] = points
            self.load_cloud_on_completion(points, self.tr("Solar fields"), self.POINTS, context, feedback)
        return results
