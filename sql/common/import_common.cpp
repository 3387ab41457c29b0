#include "rayscan/sql/import.hpp"

#include "rayscan/base/ascii_case.hpp"

#include <stdexcept>
#include <vector>

namespace rayscan::sql {

bool is_sql_identifier(const std::string& s, std::size_t max_len, bool allow_upper) {
  if (s.empty() || s.size() > max_len) return false;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const char c = s[i];
    const bool alpha = (c >= 'a' && c <= 'z') || (allow_upper && c >= 'A' && c <= 'Z') || c == '_';
    if (!alpha && !(i > 0 && c >= '0' && c <= '9')) return false;
  }
  return true;
}

std::string folded_sql_name(std::string s) { return ascii_lower(s); }

namespace {

// Column names the engines reserve for their own columns: SQLite's row id (sqlite.org/lang_createtable.html,
// "ROWID and the INTEGER PRIMARY KEY") and PostgreSQL's system columns (PostgreSQL 15 documentation,
// section 5.5 "System Columns"; oid up to PostgreSQL 11).
constexpr const char* kSqliteColumns[] = {"rowid", "oid", "_rowid_"};
constexpr const char* kPostgresColumns[] = {"tableoid", "xmin", "cmin", "xmax", "cmax", "ctid", "oid"};

// PostgreSQL's key words that cannot name a table or column unquoted: the categories "reserved" and
// "reserved (can be function or type)" of PostgreSQL 15's Appendix C (catcode R and T of
// pg_get_keywords(); tests/sql compares the list with a real server's).
constexpr const char* kPostgresKeywords[] = {
    "all", "analyse", "analyze", "and", "any", "array", "as", "asc", "asymmetric", "authorization",
    "binary", "both", "case", "cast", "check", "collate", "collation", "column", "concurrently",
    "constraint", "create", "cross", "current_catalog", "current_date", "current_role",
    "current_schema", "current_time", "current_timestamp", "current_user", "default", "deferrable",
    "desc", "distinct", "do", "else", "end", "except", "false", "fetch", "for", "foreign", "freeze",
    "from", "full", "grant", "group", "having", "ilike", "in", "initially", "inner", "intersect",
    "into", "is", "isnull", "join", "lateral", "leading", "left", "like", "limit", "localtime",
    "localtimestamp", "natural", "not", "notnull", "null", "offset", "on", "only", "or", "order",
    "outer", "overlaps", "placing", "primary", "references", "returning", "right", "select",
    "session_user", "similar", "some", "symmetric", "table", "tablesample", "then", "to", "trailing",
    "true", "union", "unique", "user", "using", "variadic", "verbose", "when", "where", "window",
    "with"};

template <std::size_t N>
bool listed(const char* const (&list)[N], const std::string& s) {
  for (const char* w : list)
    if (s == w) return true;
  return false;
}

}  // namespace

std::string reserved_sql_name(const std::string& name, bool column) {
  const std::string f = folded_sql_name(name);
  if (column && listed(kSqliteColumns, f))
    return "'" + f + "' is SQLite's row id (reserved column names: rowid, oid, _rowid_, tableoid, "
           "xmin, cmin, xmax, cmax, ctid)";
  if (column && listed(kPostgresColumns, f))
    return "'" + f + "' is a system column of PostgreSQL (reserved column names: rowid, oid, "
           "_rowid_, tableoid, xmin, cmin, xmax, cmax, ctid)";
  if (listed(kPostgresKeywords, f)) return "'" + f + "' is a reserved key word of PostgreSQL";
  return "";
}

void check_attribute_names(const std::vector<std::string>& names, bool pcpatch) {
  // SQL names are case-insensitive: PostgreSQL folds an unquoted name to lower case and SQLite
  // compares names without case, so "GpsTime" and "gpstime", or "X" and the built-in x, would be
  // one column (the database's own error, or two attributes merged).
  struct Taken {
    std::string folded, column, attribute;  // attribute empty: a built-in column
  };
  std::vector<Taken> taken;
  for (const char* b : {"point_index", "source", "chunk", "x", "y", "z"}) taken.push_back({b, b, ""});
  if (pcpatch) taken.push_back({"pointindex", "PointIndex", ""});  // (the pgpointcloud schema's dimension)
  for (const std::string& n : names) {
    if (!is_sql_identifier(n, 63, true))
      throw std::invalid_argument("attribute '" + n + "': expected an SQL identifier [A-Za-z_][A-Za-z0-9_]*");
    if (const std::string why = reserved_sql_name(n, true); !why.empty())
      throw std::invalid_argument("attribute '" + n + "': " + why + "; expected another name");
    const std::vector<std::string> columns =
        n == "rgb" ? std::vector<std::string>{"red", "green", "blue"} : std::vector<std::string>{n};
    for (const std::string& col : columns) {
      const std::string f = folded_sql_name(col);
      for (const Taken& t : taken) {
        if (t.folded != f) continue;
        if (t.attribute == n) throw std::invalid_argument("attribute '" + n + "' is asked twice");
        const std::string why = t.column == col ? "" : " (SQL names ignore case)";
        if (t.attribute.empty())
          throw std::invalid_argument("attribute '" + n + "': its column '" + col + "' would be the built-in column '" +
                                      t.column + "'" + why);
        throw std::invalid_argument("attribute '" + n + "': its column '" + col + "' would be the column '" +
                                    t.column + "' of attribute '" + t.attribute + "'" + why);
      }
      taken.push_back({f, col, n});
    }
  }
}

std::vector<AttributeColumn> resolve_attributes(const std::vector<std::string>& names,
                                                const std::vector<std::filesystem::path>& paths,
                                                const std::vector<PointCloud>& clouds) {
  std::vector<AttributeColumn> cols;
  auto need = [&](const std::string& name, auto has) {
    for (std::size_t i = 0; i < clouds.size(); ++i)
      if (!clouds[i].empty() && !has(clouds[i]))
        throw std::invalid_argument(paths[i].string() + ": attribute '" + name +
                                    "' requested but the file has none");
  };
  check_attribute_names(names);
  for (const std::string& n : names) {
    if (n == "intensity") {
      need(n, [](const PointCloud& c) { return !c.intensity.empty(); });
      cols.push_back({n, true, [](const PointCloud& c, std::size_t i) { return double(c.intensity[i]); }});
    } else if (n == "classification") {
      need(n, [](const PointCloud& c) { return !c.classification.empty(); });
      cols.push_back({n, true, [](const PointCloud& c, std::size_t i) { return double(c.classification[i]); }});
    } else if (n == "gps_time") {
      need(n, [](const PointCloud& c) { return !c.gps_time.empty(); });
      cols.push_back({n, false, [](const PointCloud& c, std::size_t i) { return c.gps_time[i]; }});
    } else if (n == "rgb") {
      need(n, [](const PointCloud& c) { return !c.rgb.empty(); });
      cols.push_back({"red", true, [](const PointCloud& c, std::size_t i) { return double(c.rgb[i].r); }});
      cols.push_back({"green", true, [](const PointCloud& c, std::size_t i) { return double(c.rgb[i].g); }});
      cols.push_back({"blue", true, [](const PointCloud& c, std::size_t i) { return double(c.rgb[i].b); }});
    } else {
      need(n, [&](const PointCloud& c) { return c.scalar(n) != nullptr; });
      cols.push_back({n, false, [n](const PointCloud& c, std::size_t i) { return c.scalar(n)->values[i]; }});
    }
  }
  return cols;
}

}  // namespace rayscan::sql
