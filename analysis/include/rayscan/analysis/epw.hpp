// EnergyPlus weather files (EPW): the subset the solar job needs. Format: EnergyPlus "Auxiliary
// Programs", chapter "Weather Converter Program", section "EnergyPlus Weather File (EPW) Data
// Dictionary": 8 header lines (LOCATION, DESIGN CONDITIONS, TYPICAL/EXTREME PERIODS, GROUND
// TEMPERATURES, HOLIDAYS/DAYLIGHT SAVINGS, COMMENTS 1, COMMENTS 2, DATA PERIODS), then one line
// of 35 comma-separated fields per record.
//
// Time. A record's hour field is 1..24 in local STANDARD time (no daylight saving) and the
// radiation fields are the energy received "during the number of minutes preceding the time
// indicated": hour 1 is 00:00-01:00. A record is therefore an integral over an interval, and the
// instant that represents it best (for the sun position to pair with it) is the middle of that
// interval: EpwRecord::utc_mid = local standard end time - interval / 2 - time zone.
//
// Years. A typical-year file takes each month from another year, so its records are read by
// month/day/hour and laid onto the calendar year wanted (epw_utc_mid), day for day. 29 February
// may be present or not whatever the year field says (EnergyPlus reads both): a caller decides
// what a leap day missing from the file, or a file's leap day in a non-leap year, becomes.
#pragma once

#include <chrono>
#include <cstddef>
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace rayscan::analysis {

/// The LOCATION header line.
struct EpwLocation {
  std::string city, state_province, country, source, wmo;
  double latitude_deg = 0.0;     ///< + north, -90..90
  double longitude_deg = 0.0;    ///< + east, -180..180
  double time_zone_hours = 0.0;  ///< local standard time - UTC, hours, -12..14
  double elevation_m = 0.0;      ///< -1000..9999.9 m
};

/// One data period of the DATA PERIODS header line (dates as month/day, no year).
struct EpwDataPeriod {
  std::string name;
  std::string start_weekday;
  int start_month = 1, start_day = 1, end_month = 12, end_day = 31;
};

/// One data record. Radiation values are the file's Wh/m^2 over the record's interval, which for
/// hourly files is the mean irradiance in W/m^2 over the hour ending at the time stamp (for
/// sub-hourly files EnergyPlus treats the value as the interval's mean W/m^2, as this reader's
/// callers should). A missing value (the dictionary's "missing" code) is NaN.
struct EpwRecord {
  int year = 0;    ///< field 1, as in the file (typical-year files mix years)
  int month = 0;   ///< field 2, 1..12
  int day = 0;     ///< field 3, 1..days in month (29 February in any year, after 28 February)
  int hour = 0;    ///< field 4, 1..24: the interval ends at hour:00 (hourly files)
  int minute = 0;  ///< field 5, 0..60; used only with several records per hour
  /// UTC instant in the middle of the record's interval (see the file comment), in the record's
  /// own `year`. For 29 February in a year without one it is 1 March's instant (std::chrono's
  /// reading of that date): use epw_utc_mid to lay a file on a calendar year.
  std::chrono::sys_seconds utc_mid{};
  /// utc_mid minus 00:00 of the record's month/day (as a UTC date): the local standard end time
  /// - interval / 2 - time zone, the same in every year; may be negative (east of UTC).
  std::chrono::seconds mid_of_day{};
  double dry_bulb_c = 0.0;   ///< field 7, degrees C (missing 99.9 -> NaN)
  double pressure_pa = 0.0;  ///< field 10, station pressure, Pa (missing 999999 -> NaN)
  double ghi = 0.0;          ///< field 14, Global Horizontal Radiation (missing 9999 -> NaN)
  double dni = 0.0;          ///< field 15, Direct Normal Radiation (missing 9999 -> NaN)
  double dhi = 0.0;          ///< field 16, Diffuse Horizontal Radiation (missing 9999 -> NaN)
  double albedo = 0.0;       ///< field 33, 0..1 (missing 999 -> NaN)
};

/// Reading options.
struct EpwReadOptions {
  /// Missing radiation (9999 in GHI, DNI or DHI): false keeps the record with NaN (the caller
  /// skips or fills that interval; EpwFile::missing_radiation counts them); true makes it an
  /// error naming the line and field.
  bool missing_radiation_is_error = false;
};

/// A read EPW file.
struct EpwFile {
  EpwLocation location;
  int records_per_hour = 1;            ///< DATA PERIODS field 2, 1..60, dividing 60
  std::vector<EpwDataPeriod> periods;  ///< DATA PERIODS, at least one
  std::vector<EpwRecord> records;      ///< in file order: consecutive intervals
  std::size_t missing_radiation = 0;   ///< records with GHI, DNI or DHI missing
};

/// Reads an EPW file. Validation (every failure throws std::runtime_error with one line of the
/// form "<path>: line <n>: field <k> '<EPW field name>': expected <what>, got '<text>'", or
/// "<path>: line <n>: <problem>" for a whole line, or "<path>: <problem>" for the file):
///  * the 8 header lines must start with their keywords; LOCATION's latitude, longitude, time
///    zone and elevation must be numbers in range; DATA PERIODS must give 1..12 periods, the
///    records per hour (1..60, dividing 60) and each period's start and end as month/day
///    (" 1/ 1" style, optionally /year) or a day of the year;
///  * every record has exactly 35 fields; month/day/hour/minute are integers in range and the
///    records follow each other without gaps (29 February may be present or not) from the first
///    period's start to the last period's end; the record count must be the one the periods
///    imply (8760, or 8784 with 29 February, for a full year of hourly data);
///  * numeric fields must be plain numbers (finite, no trailing text) within the dictionary's
///    ranges: dry bulb -70..70 C, pressure 31000..120000 Pa, radiation 0..9999 Wh/m^2 (9999 =
///    missing), albedo 0..1 (999 = missing). Fields not listed here are not checked;
///  * CR LF line ends are accepted; a line over 1 MiB, a NUL byte, blank lines between records
///    and an empty file are errors. Blank lines after the last record are ignored.
/// The file is read under the input policy (rayscan/base/input_file.hpp): a regular file of at
/// most 256 MiB, else InputFileError (a std::runtime_error) "<path>: <reason>", e.g. "is a FIFO,
/// not a regular file"; the same when the file cannot be opened.
EpwFile read_epw(const std::filesystem::path& path, const EpwReadOptions& options = {});

/// As read_epw, from a stream; `name` stands for the path in messages.
EpwFile parse_epw(std::istream& in, std::string_view name, const EpwReadOptions& options = {});

/// `record`'s utc_mid had its month/day been in calendar year `year` (the record's own year
/// ignored): 00:00 of year/month/day + mid_of_day. nullopt for 29 February when `year` is not a
/// leap year: that day does not exist there.
std::optional<std::chrono::sys_seconds> epw_utc_mid(const EpwRecord& record, int year);

}  // namespace rayscan::analysis
