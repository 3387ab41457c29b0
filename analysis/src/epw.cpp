// EnergyPlus weather file reader: the EPW data dictionary (EnergyPlus "Auxiliary Programs",
// "Weather Converter Program", "EnergyPlus Weather File (EPW) Data Dictionary").
#include "rayscan/analysis/epw.hpp"

#include "rayscan/base/input_file.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <istream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

namespace rayscan::analysis {
// Named (and anonymous inside) so that a unity build can merge this file with others.
namespace epw_impl {
namespace {

constexpr std::size_t kMaxLineLength = 1u << 20;
constexpr std::size_t kRecordFields = 35;
constexpr int kMaxPeriods = 12;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The dictionary's names of the 35 data fields (N1..N5, A1, N6..N34), field k at index k - 1.
constexpr std::array<const char*, kRecordFields> kFieldNames = {
    "Year",
    "Month",
    "Day",
    "Hour",
    "Minute",
    "Data Source and Uncertainty Flags",
    "Dry Bulb Temperature",
    "Dew Point Temperature",
    "Relative Humidity",
    "Atmospheric Station Pressure",
    "Extraterrestrial Horizontal Radiation",
    "Extraterrestrial Direct Normal Radiation",
    "Horizontal Infrared Radiation Intensity",
    "Global Horizontal Radiation",
    "Direct Normal Radiation",
    "Diffuse Horizontal Radiation",
    "Global Horizontal Illuminance",
    "Direct Normal Illuminance",
    "Diffuse Horizontal Illuminance",
    "Zenith Luminance",
    "Wind Direction",
    "Wind Speed",
    "Total Sky Cover",
    "Opaque Sky Cover",
    "Visibility",
    "Ceiling Height",
    "Present Weather Observation",
    "Present Weather Codes",
    "Precipitable Water",
    "Aerosol Optical Depth",
    "Snow Depth",
    "Days Since Last Snowfall",
    "Albedo",
    "Liquid Precipitation Depth",
    "Liquid Precipitation Quantity"};

constexpr std::array<const char*, 8> kHeaderKeywords = {
    "LOCATION",
    "DESIGN CONDITIONS",
    "TYPICAL/EXTREME PERIODS",
    "GROUND TEMPERATURES",
    "HOLIDAYS/DAYLIGHT SAVING",  // the dictionary's spelling; files add an S
    "COMMENTS 1",
    "COMMENTS 2",
    "DATA PERIODS"};

constexpr std::array<int, 12> kDaysInMonth = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

// The text of a field as quoted in a message: printable, one line, at most 40 characters.
std::string echo(std::string_view s) {
  std::string out;
  for (const char c : s.substr(0, 40)) out += std::isprint(static_cast<unsigned char>(c)) ? c : '?';
  if (s.size() > 40) out += "...";
  return out;
}

// Reads lines of a stream (LF or CR LF), bounded in length, and builds the one-line errors.
class Reader {
 public:
  Reader(std::istream& in, std::string_view name) : in_(in), name_(name) {}

  // Next line without its line end; false at the end of the stream.
  bool next(std::string& line) {
    line.clear();
    std::streambuf* buf = in_.rdbuf();
    if (!buf) fail_file("unreadable stream");
    int c = buf->sbumpc();
    if (c == std::char_traits<char>::eof()) return false;
    ++line_no_;
    while (c != std::char_traits<char>::eof() && c != '\n') {
      if (line.size() >= kMaxLineLength)
        fail_line("longer than " + std::to_string(kMaxLineLength) + " characters");
      if (c == '\0') fail_line("contains a NUL byte (not a text file?)");
      line += static_cast<char>(c);
      c = buf->sbumpc();
    }
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  }

  std::size_t line_no() const { return line_no_; }

  [[noreturn]] void fail_file(const std::string& what) const {
    throw std::runtime_error(name_ + ": " + what);
  }
  [[noreturn]] void fail_line(const std::string& what) const {
    throw std::runtime_error(name_ + ": line " + std::to_string(line_no_) + ": " + what);
  }
  [[noreturn]] void fail_field(std::size_t field, std::string_view field_name,
                               const std::string& expected, std::string_view got) const {
    fail_line("field " + std::to_string(field) + " '" + std::string(field_name) + "': expected " +
              expected + ", got '" + echo(got) + "'");
  }

 private:
  std::istream& in_;
  std::string name_;
  std::size_t line_no_ = 0;
};

// Splits at commas into `out` (views into `line`); false when there are more than `max` fields.
bool split(std::string_view line, std::vector<std::string_view>& out, std::size_t max) {
  out.clear();
  std::size_t start = 0;
  for (;;) {
    if (out.size() == max) return false;
    const std::size_t comma = line.find(',', start);
    out.push_back(line.substr(start, comma == std::string_view::npos ? line.npos : comma - start));
    if (comma == std::string_view::npos) return true;
    start = comma + 1;
  }
}

std::size_t count_fields(std::string_view line) {
  return static_cast<std::size_t>(std::count(line.begin(), line.end(), ',')) + 1;
}

// A plain decimal number (optional sign, digits, point, exponent), finite; nullopt otherwise.
std::optional<double> to_double(std::string_view s) {
  s = trim(s);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty() || !(std::isdigit(static_cast<unsigned char>(s.front())) || s.front() == '-' ||
                     s.front() == '.'))
    return std::nullopt;
  double v = 0.0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::optional<int> to_int(std::string_view s) {
  s = trim(s);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  int v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc() || end != s.data() + s.size()) return std::nullopt;
  return v;
}

std::string range_text(double lo, double hi) {
  auto num = [](double v) {
    std::string t = std::to_string(v);
    t.erase(t.find_last_not_of('0') + 1);
    if (t.back() == '.') t.pop_back();
    return t;
  };
  return num(lo) + ".." + num(hi);
}

double number_in(const Reader& r, const std::vector<std::string_view>& f, std::size_t field,
                 std::string_view name, double lo, double hi) {
  const std::optional<double> v = to_double(f[field - 1]);
  if (!v || *v < lo || *v > hi)
    r.fail_field(field, name, "a number in " + range_text(lo, hi), f[field - 1]);
  return *v;
}

int int_in(const Reader& r, const std::vector<std::string_view>& f, std::size_t field,
           std::string_view name, int lo, int hi) {
  const std::optional<int> v = to_int(f[field - 1]);
  if (!v || *v < lo || *v > hi)
    r.fail_field(field, name, "an integer in " + std::to_string(lo) + ".." + std::to_string(hi),
                 f[field - 1]);
  return *v;
}

// A measured value with a missing code: NaN for the code, else a number in lo..hi.
double measured(const Reader& r, const std::vector<std::string_view>& f, std::size_t field,
                double lo, double hi, double missing, const std::string& missing_text) {
  const std::optional<double> v = to_double(f[field - 1]);
  if (v && *v == missing) return kNaN;
  if (!v || *v < lo || *v > hi)
    r.fail_field(field, kFieldNames[field - 1],
                 "a number in " + range_text(lo, hi) + " (" + missing_text + " = missing)",
                 f[field - 1]);
  return *v + 0.0;  // "-0.00" (seen in PVGIS files) as +0
}

bool keyword_is(std::string_view field, std::string_view keyword) {
  field = trim(field);
  if (field.size() < keyword.size()) return false;
  for (std::size_t i = 0; i < keyword.size(); ++i)
    if (std::toupper(static_cast<unsigned char>(field[i])) != keyword[i]) return false;
  return true;
}

EpwLocation parse_location(const Reader& r, const std::vector<std::string_view>& f) {
  if (f.size() < 10)
    r.fail_line(
        "LOCATION: expected 10 comma-separated fields (LOCATION, city, state, country, "
        "source, WMO, latitude, longitude, time zone, elevation), got " +
        std::to_string(f.size()));
  EpwLocation loc;
  loc.city = std::string(trim(f[1]));
  loc.state_province = std::string(trim(f[2]));
  loc.country = std::string(trim(f[3]));
  loc.source = std::string(trim(f[4]));
  loc.wmo = std::string(trim(f[5]));
  loc.latitude_deg = number_in(r, f, 7, "Latitude", -90.0, 90.0);
  loc.longitude_deg = number_in(r, f, 8, "Longitude", -180.0, 180.0);
  loc.time_zone_hours = number_in(r, f, 9, "TimeZone", -12.0, 14.0);
  loc.elevation_m = number_in(r, f, 10, "Elevation", -1000.0, 9999.9);
  return loc;
}

// A DATA PERIODS date: "m/d", "m/d/y" (year ignored) or a day of the (non-leap) year.
bool parse_period_date(std::string_view s, int& month, int& day) {
  s = trim(s);
  const std::size_t slash = s.find('/');
  if (slash == std::string_view::npos) {
    const std::optional<int> doy = to_int(s);
    if (!doy || *doy < 1 || *doy > 365) return false;
    int d = *doy;
    month = 1;
    while (d > kDaysInMonth[static_cast<std::size_t>(month - 1)])
      d -= kDaysInMonth[static_cast<std::size_t>(month++ - 1)];
    day = d;
    return true;
  }
  std::string_view rest = s.substr(slash + 1);
  const std::size_t slash2 = rest.find('/');
  if (slash2 != std::string_view::npos) {
    if (!to_int(rest.substr(slash2 + 1))) return false;
    rest = rest.substr(0, slash2);
  }
  const std::optional<int> m = to_int(s.substr(0, slash)), d = to_int(rest);
  if (!m || !d || *m < 1 || *m > 12) return false;
  const int max_day = *m == 2 ? 29 : kDaysInMonth[static_cast<std::size_t>(*m - 1)];
  if (*d < 1 || *d > max_day) return false;
  month = *m;
  day = *d;
  return true;
}

void parse_data_periods(const Reader& r, const std::vector<std::string_view>& f, EpwFile& file) {
  if (f.size() < 3)
    r.fail_line("DATA PERIODS: expected the number of periods and the records per hour");
  const int periods = int_in(r, f, 2, "Number of Data Periods", 1, kMaxPeriods);
  file.records_per_hour = int_in(r, f, 3, "Number of Records per hour", 1, 60);
  if (60 % file.records_per_hour != 0)
    r.fail_field(3, "Number of Records per hour", "a divisor of 60", f[2]);
  const std::size_t needed = 3 + 4 * static_cast<std::size_t>(periods);
  if (f.size() < needed)
    r.fail_line("DATA PERIODS: expected " + std::to_string(needed) + " fields for " +
                std::to_string(periods) +
                " period(s) (name, start weekday, start, end each), got " +
                std::to_string(f.size()));
  for (int p = 0; p < periods; ++p) {
    const std::size_t base = 4 + 4 * static_cast<std::size_t>(p);  // field number of the name
    EpwDataPeriod period;
    period.name = std::string(trim(f[base - 1]));
    period.start_weekday = std::string(trim(f[base]));
    const std::string n = std::to_string(p + 1);
    if (!parse_period_date(f[base + 1], period.start_month, period.start_day))
      r.fail_field(base + 2, "Data Period " + n + " Start Day",
                   "a date as month/day or a day of the year", f[base + 1]);
    if (!parse_period_date(f[base + 2], period.end_month, period.end_day))
      r.fail_field(base + 3, "Data Period " + n + " End Day",
                   "a date as month/day or a day of the year", f[base + 2]);
    file.periods.push_back(period);
  }
}

// Reads and checks the 8 header lines.
void parse_header(Reader& r, std::string& line, std::vector<std::string_view>& f, EpwFile& file) {
  for (std::size_t i = 0; i < kHeaderKeywords.size(); ++i) {
    if (!r.next(line)) {
      if (i == 0)
        r.fail_file("empty file (expected the 8 EPW header lines, starting with LOCATION)");
      r.fail_file("ends after " + std::to_string(i) + " header line(s); expected 8 (the next is " +
                  kHeaderKeywords[i] + ")");
    }
    split(line, f, kMaxLineLength);
    if (!keyword_is(f[0], kHeaderKeywords[i]))
      r.fail_line(std::string("expected the header line starting with '") + kHeaderKeywords[i] +
                  ",', got '" + echo(line) + "'");
    if (i == 0) file.location = parse_location(r, f);
    if (i + 1 == kHeaderKeywords.size()) parse_data_periods(r, f, file);
  }
}

int day_of_year(int month, int day) {
  int doy = day;
  for (int m = 1; m < month; ++m) doy += kDaysInMonth[static_cast<std::size_t>(m - 1)];
  return std::min(doy, 365);  // 29 February counts as 28 February here
}

// Walks the expected sequence of intervals over the data periods and checks each record's
// month/day/hour against it; also computes the record count the periods imply.
class Sequence {
 public:
  explicit Sequence(const EpwFile& file)
      : periods_(file.periods), per_hour_(file.records_per_hour) {
    for (const EpwDataPeriod& p : periods_) {
      const int days =
          (day_of_year(p.end_month, p.end_day) - day_of_year(p.start_month, p.start_day) + 365) %
              365 +
          1;
      expected_ += static_cast<std::size_t>(days) * 24 * static_cast<std::size_t>(per_hour_);
    }
    start_period(0);
  }

  bool done() const { return period_ >= periods_.size(); }
  // The record count the periods imply, including 29 February when the file has it.
  std::size_t expected() const {
    return expected_ + (leap_day_seen_ ? 24 * static_cast<std::size_t>(per_hour_) : 0);
  }
  int sub_interval() const { return sub_; }  // 1..records per hour within the hour

  // Checks the next record's month/day/hour, then advances.
  void check_and_advance(const Reader& r, int month, int day, int hour) {
    const bool leap_day = month == 2 && day == 29 && month_ == 3 && day_ == 1 && hour_ == 1 &&
                          sub_ == 1 && !in_leap_day_;
    if (leap_day) {
      leap_day_seen_ = in_leap_day_ = true;
      month_ = 2;
      day_ = 29;
    }
    if (month != month_ || day != day_ || hour != hour_)
      r.fail_line("fields 2-4 'Month', 'Day', 'Hour': expected " + std::to_string(month_) + "/" +
                  std::to_string(day_) + " hour " + std::to_string(hour_) +
                  " (the records must follow each other through the DATA PERIODS), got " +
                  std::to_string(month) + "/" + std::to_string(day) + " hour " +
                  std::to_string(hour));
    advance();
  }

 private:
  void start_period(std::size_t p) {
    period_ = p;
    if (done()) return;
    month_ = periods_[p].start_month;
    day_ = periods_[p].start_day;
    hour_ = 1;
    sub_ = 1;
  }

  void advance() {
    const EpwDataPeriod& p = periods_[period_];
    if (sub_ < per_hour_) {
      ++sub_;
      return;
    }
    sub_ = 1;
    if (hour_ < 24) {
      ++hour_;
      return;
    }
    hour_ = 1;
    const bool period_end = month_ == p.end_month && day_ == p.end_day;
    if (period_end) {
      start_period(period_ + 1);
      return;
    }
    if (in_leap_day_) {  // 29 February -> 1 March
      in_leap_day_ = false;
      month_ = 3;
      day_ = 1;
    } else if (day_ < kDaysInMonth[static_cast<std::size_t>(month_ - 1)]) {
      ++day_;
    } else {
      month_ = month_ % 12 + 1;
      day_ = 1;
    }
  }

  const std::vector<EpwDataPeriod>& periods_;
  int per_hour_;
  std::size_t expected_ = 0, period_ = 0;
  int month_ = 1, day_ = 1, hour_ = 1, sub_ = 1;
  bool leap_day_seen_ = false, in_leap_day_ = false;
};

// One data line into a record (fields already split, 35 of them).
EpwRecord parse_record(const Reader& r, const std::vector<std::string_view>& f,
                       const EpwReadOptions& options, int per_hour, int sub_interval,
                       double time_zone_hours) {
  EpwRecord rec;
  rec.year = int_in(r, f, 1, kFieldNames[0], 0, 9999);
  rec.month = int_in(r, f, 2, kFieldNames[1], 1, 12);
  rec.hour = int_in(r, f, 4, kFieldNames[3], 1, 24);
  rec.minute = int_in(r, f, 5, kFieldNames[4], 0, 60);
  // 29 February whatever the year field: a typical year's February comes from some year, and a
  // file built for leap years keeps it (Sequence checks it follows 28 February).
  const int max_day = rec.month == 2 ? 29 : kDaysInMonth[static_cast<std::size_t>(rec.month - 1)];
  rec.day = int_in(r, f, 3, kFieldNames[2], 1, max_day);

  rec.dry_bulb_c = measured(r, f, 7, -70.0, 70.0, 99.9, "99.9");
  rec.pressure_pa = measured(r, f, 10, 31000.0, 120000.0, 999999.0, "999999");
  rec.ghi = measured(r, f, 14, 0.0, 9999.0, 9999.0, "9999");
  rec.dni = measured(r, f, 15, 0.0, 9999.0, 9999.0, "9999");
  rec.dhi = measured(r, f, 16, 0.0, 9999.0, 9999.0, "9999");
  rec.albedo = measured(r, f, 33, 0.0, 1.0, 999.0, "999");
  if (options.missing_radiation_is_error) {
    for (const std::size_t field : {14u, 15u, 16u})
      if (to_double(f[field - 1]) == 9999.0)
        r.fail_field(field, kFieldNames[field - 1], "a measured value (missing data refused)",
                     f[field - 1]);
  }

  // The interval ends at (hour - 1) h + sub_interval * (60 / per_hour) min, local standard time.
  using namespace std::chrono;
  const seconds interval{3600 / per_hour};
  // A date that does not exist (29 February of a non-leap year) is counted on by sys_days: 1 March.
  const sys_days date{std::chrono::year{rec.year} / rec.month / rec.day};
  const seconds end = hours{rec.hour - 1} + interval * sub_interval;
  const seconds zone{static_cast<long long>(std::llround(time_zone_hours * 3600.0))};
  rec.mid_of_day = end - interval / 2 - zone;
  rec.utc_mid = sys_seconds{date} + rec.mid_of_day;
  return rec;
}

}  // namespace
}  // namespace epw_impl

EpwFile parse_epw(std::istream& in, std::string_view name, const EpwReadOptions& options) {
  using namespace epw_impl;
  Reader r(in, name);
  EpwFile file;
  std::string line;
  std::vector<std::string_view> f;
  parse_header(r, line, f, file);

  Sequence seq(file);
  file.records.reserve(std::min<std::size_t>(seq.expected(), 8784 * 4));
  while (r.next(line)) {
    if (trim(line).empty()) {  // only blank lines may follow the last record
      const std::size_t blank = r.line_no();
      while (r.next(line))
        if (!trim(line).empty())
          r.fail_line("data record after a blank line (line " + std::to_string(blank) + ")");
      break;
    }
    if (seq.done())
      r.fail_line("more data records than DATA PERIODS declares (" +
                  std::to_string(seq.expected()) + ")");
    if (!split(line, f, kRecordFields) || f.size() != kRecordFields)
      r.fail_line("expected " + std::to_string(kRecordFields) +
                  " comma-separated fields in a data record, got " +
                  std::to_string(count_fields(line)));
    const int sub = seq.sub_interval();
    EpwRecord rec =
        parse_record(r, f, options, file.records_per_hour, sub, file.location.time_zone_hours);
    seq.check_and_advance(r, rec.month, rec.day, rec.hour);
    if (std::isnan(rec.ghi) || std::isnan(rec.dni) || std::isnan(rec.dhi)) ++file.missing_radiation;
    file.records.push_back(rec);
  }
  if (!seq.done())
    r.fail_file("expected " + std::to_string(seq.expected()) +
                " data records (as DATA PERIODS declares), the file ends after " +
                std::to_string(file.records.size()));
  return file;
}

std::optional<std::chrono::sys_seconds> epw_utc_mid(const EpwRecord& record, int year) {
  using namespace std::chrono;
  const year_month_day date{std::chrono::year{year} / record.month / record.day};
  if (!date.ok()) return std::nullopt;
  return sys_seconds{sys_days{date}} + record.mid_of_day;
}

EpwFile read_epw(const std::filesystem::path& path, const EpwReadOptions& options) {
  // The input policy (regular file, never a blocking open, 256 MiB cap): a year of one-minute
  // records is about 80 MB.
  std::istringstream in(read_text_file(path));
  return parse_epw(in, path.string(), options);
}

}  // namespace rayscan::analysis
