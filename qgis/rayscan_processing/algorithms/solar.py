"""Solar: `rayscan solar CLOUD --start/--end or --at ... --raster MAP.tif --cell C [-o OUT.las]`."""

from qgis.core import (QgsProcessingException, QgsProcessingParameterDefinition,
                       QgsProcessingParameterEnum, QgsProcessingParameterFileDestination,
                       QgsProcessingParameterNumber, QgsProcessingParameterRasterDestination,
                       QgsProcessingParameterString)

from . import styles
from .base import GEOTIFF_EXTENSIONS, POINTS_FILTER, PRIMITIVES, RayscanAlgorithm

_MODES = ["period (irradiation, kWh/m²)", "instant (shadows)"]
# `rayscan solar --raster-value` (its help): a period's values, then the one only an instant has
# (an instant also takes global, beam and diffuse). The CLI refuses a value the mode lacks.
_VALUES = ["global", "beam", "diffuse", "reflected", "sun_hours", "sky_view", "in_shadow"]


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
    FLAGS = {"START": "--start", "END": "--end", "STEP": "--step", "AT": "--at", "VALUE": "--raster-value",
             "CELL": "--cell", "LATITUDE": "--lat,--latitude", "LONGITUDE": "--lon,--longitude",
             "LINKE": "--linke", "SECTOR": "--sector", "PRIMITIVE": "--primitive", "OUTPUT": "--raster",
             "POINTS": "-o,--out"}

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
        self.addParameter(QgsProcessingParameterEnum(
            "VALUE", self.tr("Map value"),
            [self.tr("default (global for a period, in_shadow for an instant)")] + _VALUES, defaultValue=0))
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
        ]
        for p in advanced:
            p.setFlags(p.flags() | QgsProcessingParameterDefinition.FlagAdvanced)
            self.addParameter(p)
        # The CLI's default geometry for shadows is the sphere.
        self.add_primitive_parameter("Geometry that casts shadows", "sphere", advanced=True)
        self.addParameter(QgsProcessingParameterRasterDestination(self.OUTPUT, self.tr("Solar map")))
        self.addParameter(QgsProcessingParameterFileDestination(
            self.POINTS, self.tr("Cloud with solar fields"), POINTS_FILTER, optional=True,
            createByDefault=False))

    def processAlgorithm(self, parameters, context, feedback):  # noqa: N802 (QGIS's name)
        """Run rayscan solar and return the raster (and the cloud when asked)."""
        cloud = self.cloud(parameters, context)
        out = self.parameterAsOutputLayer(parameters, self.OUTPUT, context)
        self.check_extension(out, GEOTIFF_EXTENSIONS, "The solar map")
        args = (["solar", cloud] + self.option("OUTPUT", out) + ["--no-preview"]
                + self.option("CELL", self.parameterAsDouble(parameters, "CELL", context))
                + self.option("LINKE", self.parameterAsDouble(parameters, "LINKE", context))
                + self.option("SECTOR", self.parameterAsDouble(parameters, "SECTOR", context))
                + self.option("PRIMITIVE", PRIMITIVES[self.parameterAsEnum(parameters, "PRIMITIVE", context)]))
        instant = self.parameterAsEnum(parameters, "MODE", context) == 1
        if not instant:
            start = self.parameterAsString(parameters, "START", context).strip()
            end = self.parameterAsString(parameters, "END", context).strip()
            missing = [name for name, value in (("START", start), ("END", end)) if not value]
            if missing:
                raise QgsProcessingException(self.tr("{} '{}' needs {} and {}; {} empty").format(
                    self.label("MODE"), _MODES[0], self.label("START"), self.label("END"),
                    " and ".join(missing) + (" are" if len(missing) > 1 else " is")))
            args += (self.option("START", start) + self.option("END", end)
                     + self.option("STEP", self.parameterAsString(parameters, "STEP", context).strip() or "1h"))
        else:
            at = self.parameterAsString(parameters, "AT", context).strip()
            if not at:
                raise QgsProcessingException(self.tr("{} '{}' needs {}; AT is empty").format(
                    self.label("MODE"), _MODES[1], self.label("AT")))
            args += self.option("AT", at)
        value = self.parameterAsEnum(parameters, "VALUE", context)
        if value > 0:
            args += self.option("VALUE", _VALUES[value - 1])
        # An instant's default map value is in_shadow (see _VALUES).
        in_shadow = instant and (value == 0 or _VALUES[value - 1] == "in_shadow")
        for name in ("LATITUDE", "LONGITUDE"):
            given = self.given_number(parameters, name, context)
            if given is not None:
                args += self.option(name, given)
        points = self.parameterAsFileOutput(parameters, self.POINTS, context)
        if points:
            args += self.option("POINTS", points)
        self.run_cli(args, feedback)
        if in_shadow:
            styles.style_on_completion(out, styles.SHADOW, context)
        results = {self.OUTPUT: out}
        if points:
            results[self.POINTS] = points
            self.load_cloud_on_completion(points, self.tr("Solar fields"), self.POINTS, context, feedback)
        return results
