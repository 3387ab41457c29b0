// A JSON object reader for the project's JSON files (scenes, cameras, camera lists, observers):
// every file is parsed by parse_json_text, which rejects a key given twice in one object, and the
// values of scenes and cameras are read through JsonObject, which records the JSON pointer
// (RFC 6901) of what it reads so that an error names the exact field, and rejects keys it was not
// asked about. Header-only: its users link nlohmann_json; vectors are GLM's (glm::dvec3 is the
// octree's Vec3), so base needs no other room.
#pragma once

#include "rayscan/base/input_file.hpp"

#include <glm/vec3.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace rayscan::io {

/// A malformed JSON file. what() is one line: "<file>: <JSON pointer>: <what was expected>",
/// e.g. "scenes/x.json: /camera/vfov_deg: expected a number in (0, 180)". (render::SceneError.)
struct JsonFileError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

using nlohmann::json;

/// Throws JsonFileError "<file>: <ptr or />: <what>".
[[noreturn]] inline void json_fail(const std::string& file, const std::string& ptr, const std::string& what) {
  throw JsonFileError(file + ": " + (ptr.empty() ? "/" : ptr) + ": " + what);
}

/// `k` as one reference token of a JSON pointer (RFC 6901: "~" as "~0", "/" as "~1").
inline std::string escape_key(const std::string& k) {
  std::string s;
  for (char c : k) {
    if (c == '~') s += "~0";
    else if (c == '/') s += "~1";
    else s += c;
  }
  return s;
}

/// Parses JSON `text`; errors (JsonFileError) name it `name`: "<name>: byte 12: invalid JSON (...)".
/// A key given twice in one object is an error, "<name>: /camera/position: duplicate key (given twice
/// in the object /camera; expected each key once)": nlohmann would keep the last one silently, and
/// a repeated key is as likely a slip as the unknown keys the readers reject. Every JSON input
/// (scene, camera, camera list, observers) is parsed here.
inline json parse_json_text(const std::string& text, const std::string& name) {
  // Where the parser is: one frame per open object (its keys so far, the current one) or array
  // (the index of its current element), so that a duplicate is named by its JSON pointer.
  struct Frame {
    bool object = false;
    std::set<std::string> keys;
    std::string key;
    std::size_t index = 0;
    bool any = false;
  };
  std::vector<Frame> path;
  const auto element_begins = [&path] {
    if (path.empty() || path.back().object) return;
    Frame& a = path.back();
    if (a.any) ++a.index;
    a.any = true;
  };
  const auto object_pointer = [&path] {  // the innermost open object's pointer
    std::string p;
    for (std::size_t i = 0; i + 1 < path.size(); ++i) {
      p += '/';
      p += path[i].object ? escape_key(path[i].key) : std::to_string(path[i].index);
    }
    return p;
  };
  const json::parser_callback_t check = [&](int, json::parse_event_t event, json& parsed) {
    switch (event) {
      case json::parse_event_t::object_start:
      case json::parse_event_t::array_start:
        element_begins();
        path.push_back(Frame{event == json::parse_event_t::object_start, {}, {}, 0, false});
        break;
      case json::parse_event_t::object_end:
      case json::parse_event_t::array_end:
        path.pop_back();
        break;
      case json::parse_event_t::key: {
        std::string k = parsed.get<std::string>();
        if (!path.back().keys.insert(k).second) {
          const std::string object = object_pointer();
          json_fail(name, object + "/" + escape_key(k),
                    "duplicate key (given twice in the object " + (object.empty() ? "/" : object) +
                        "; expected each key once)");
        }
        path.back().key = std::move(k);
        break;
      }
      case json::parse_event_t::value:
        element_begins();
        break;
    }
    return true;
  };
  try {
    return json::parse(text, check);
  } catch (const json::parse_error& e) {
    throw JsonFileError(name + ": byte " + std::to_string(e.byte) +
                        ": invalid JSON (" + std::string(e.what()) + ")");
  } catch (const json::out_of_range& e) {
    // nlohmann reports a number beyond double (406 "number overflow parsing '1e400'") without a
    // position: find the token to name its byte offset.
    std::string what = e.what();
    const std::size_t q0 = what.find('\''), q1 = what.rfind('\'');
    std::string where = "/";
    if (q0 != std::string::npos && q1 > q0) {
      const std::size_t at = text.find(what.substr(q0 + 1, q1 - q0 - 1));
      if (at != std::string::npos) where = "byte " + std::to_string(at);
    }
    if (what.rfind("[json.exception", 0) == 0 && what.find("] ") != std::string::npos)
      what = what.substr(what.find("] ") + 2);
    throw JsonFileError(name + ": " + where + ": " + what + " (expected a finite number)");
  }
}

/// Reads and parses the JSON file `file` (the input policy of read_text_file); errors
/// (JsonFileError) name the file.
inline json parse_json_file(const std::filesystem::path& file) {
  std::string text;
  try {
    text = read_text_file(file);  // the input policy: regular file, size cap
  } catch (const InputFileError& e) {
    throw JsonFileError(e.what());
  }
  return parse_json_text(text, file.string());
}

/// A JSON object being read: typed getters with range checks, and finish() to reject unknown keys.
/// Every key a getter (or has(), at()) is asked about becomes an allowed key of the object, present
/// or not; finish() rejects the others. A getter returns its default `def` when the key is absent
/// (the default itself is not checked) and otherwise throws JsonFileError "<file>: <pointer>:
/// expected ..." when the value has the wrong type or lies outside its range.
class JsonObject {
 public:
  /// Reads the value `j` (not copied: it must outlive this reader) found at JSON pointer `ptr` ("" for
  /// the document's root) of the file `file`, which errors name. Throws JsonFileError "expected an
  /// object" when `j` is not an object.
  JsonObject(const json& j, std::string file, std::string ptr) : j_(j), file_(std::move(file)), ptr_(std::move(ptr)) {
    if (!j_.is_object()) json_fail(file_, ptr_, "expected an object");
  }
  /// Whether key `k` is present; marks `k` as an allowed key (finish() accepts it), for values
  /// that the caller reads itself.
  bool has(const std::string& k) {
    seen_.insert(k);
    return j_.contains(k);
  }
  /// Whether `k` is present, without making it an allowed key (finish() still rejects it unless
  /// a getter asks for it).
  bool present(const std::string& k) const { return j_.contains(k); }
  /// The raw value of key `k`, marked as allowed (as has()). `k` must be present: a missing key
  /// throws nlohmann's json::out_of_range, not JsonFileError, so ask has() first.
  const json& at(const std::string& k) { seen_.insert(k); return j_.at(k); }
  /// The JSON pointer of key `k` in this object (the object's pointer + "/" + the escaped key), the
  /// place an error about its value names.
  std::string ptr(const std::string& k) const { return ptr_ + "/" + escape_key(k); }
  /// The file name the errors carry.
  const std::string& file() const { return file_; }

  /// The number at key `k`, or `def` when absent: a finite JSON number within lo..hi, where
  /// `lo_open` / `hi_open` exclude that bound (true: value > lo, resp. < hi; false: >= lo,
  /// <= hi). A bound may be infinite. Throws JsonFileError "expected a number in (0, 180]" (the
  /// interval as the flags make it).
  double number(const std::string& k, double def, double lo, double hi, bool lo_open, bool hi_open) {
    if (!has(k)) return def;
    return number_at(j_.at(k), ptr(k), lo, hi, lo_open, hi_open);
  }
  /// As number(), for a value `v` already taken from the document (an array's element), named
  /// `p` in errors.
  double number_at(const json& v, const std::string& p, double lo, double hi, bool lo_open,
                   bool hi_open) const {
    const bool ok = v.is_number() && std::isfinite(v.get<double>()) &&
                    (lo_open ? v.get<double>() > lo : v.get<double>() >= lo) &&
                    (hi_open ? v.get<double>() < hi : v.get<double>() <= hi);
    if (!ok) json_fail(file_, p, "expected a number in " + range_text(lo, hi, lo_open, hi_open));
    return v.get<double>();
  }
  /// The integer at key `k`, or `def` when absent: a JSON integer (not 2.0, not negative) in
  /// [lo, hi]. Throws JsonFileError "expected an integer in [lo, hi]".
  std::uint64_t integer(const std::string& k, std::uint64_t def, std::uint64_t lo, std::uint64_t hi) {
    if (!has(k)) return def;
    const json& v = j_.at(k);
    if (!v.is_number_integer() || (v.is_number_integer() && !v.is_number_unsigned() && v.get<std::int64_t>() < 0) ||
        v.get<std::uint64_t>() < lo || v.get<std::uint64_t>() > hi)
      json_fail(file_, ptr(k), "expected an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
    return v.get<std::uint64_t>();
  }
  /// The boolean at key `k`, or `def` when absent. Throws JsonFileError "expected true or false".
  bool boolean(const std::string& k, bool def) {
    if (!has(k)) return def;
    if (!j_.at(k).is_boolean()) json_fail(file_, ptr(k), "expected true or false");
    return j_.at(k).get<bool>();
  }
  /// The string at key `k`, or `def` when absent; with `allowed` non-empty it must be one of them
  /// (exact, case-sensitive). Throws JsonFileError "expected a string", or "expected one of "a",
  /// "b"" (with ", got "x"" for a string not in the list).
  std::string string(const std::string& k, const std::string& def, const std::vector<std::string>& allowed = {}) {
    if (!has(k)) return def;
    return string_at(j_.at(k), ptr(k), allowed);
  }
  /// As string(), for a value `v` already taken from the document, named `p` in errors.
  std::string string_at(const json& v, const std::string& p, const std::vector<std::string>& allowed) const {
    std::string list;
    for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + ("\"" + a + "\"");
    if (!v.is_string()) json_fail(file_, p, allowed.empty() ? "expected a string" : "expected one of " + list);
    const std::string s = v.get<std::string>();
    if (!allowed.empty() && std::find(allowed.begin(), allowed.end(), s) == allowed.end())
      json_fail(file_, p, "expected one of " + list + ", got \"" + s + "\"");
    return s;
  }
  /// The vector at key `k`, or `def` when absent: an array of exactly 3 finite numbers; with
  /// `nonzero` (a direction, an up vector) not all three zero. Throws JsonFileError "expected an
  /// array of 3 finite numbers[, not all zero]", naming the element (".../k/1") when one element is
  /// bad.
  glm::dvec3 vec3(const std::string& k, const glm::dvec3& def, bool nonzero = false) {
    if (!has(k)) return def;
    return vec3_at(j_.at(k), ptr(k), nonzero);
  }
  /// As vec3(), for a value `v` already taken from the document, named `p` in errors.
  glm::dvec3 vec3_at(const json& v, const std::string& p, bool nonzero) const {
    const char* what = nonzero ? "expected an array of 3 finite numbers, not all zero"
                               : "expected an array of 3 finite numbers";
    if (!v.is_array() || v.size() != 3) json_fail(file_, p, what);
    glm::dvec3 r;
    for (int i = 0; i < 3; ++i) {
      if (!v[i].is_number() || !std::isfinite(v[i].get<double>())) json_fail(file_, p + "/" + std::to_string(i), what);
      r[i] = v[i].get<double>();
    }
    if (nonzero && r == glm::dvec3(0.0)) json_fail(file_, p, what);
    return r;
  }
  /// The colour at key `k`, or `def` when absent: an array of 3 linear RGB numbers, each in
  /// [0, hi]; `hi` is the largest a channel may be (1 for a material's reflectance, 1e6 for the
  /// background's and the sun's colour). Read as float. Throws JsonFileError "expected an array of
  /// 3 numbers (linear RGB) in [0, hi]", naming the element when one element is bad.
  glm::vec3 color(const std::string& k, const glm::vec3& def, float hi) {
    if (!has(k)) return def;
    return color_at(j_.at(k), ptr(k), hi);
  }
  /// As color(), for a value `v` already taken from the document, named `p` in errors.
  glm::vec3 color_at(const json& v, const std::string& p, float hi) const {
    const std::string what = "expected an array of 3 numbers (linear RGB) in [0, " + num(hi) + "]";
    if (!v.is_array() || v.size() != 3) json_fail(file_, p, what);
    glm::vec3 c;
    for (int i = 0; i < 3; ++i) {
      if (!v[i].is_number() || !(v[i].get<double>() >= 0.0) || !(v[i].get<double>() <= hi))
        json_fail(file_, p + "/" + std::to_string(i), what);
      c[i] = v[i].get<float>();
    }
    return c;
  }
  /// Rejects keys that no getter asked about: throws JsonFileError "<file>: <pointer of the key>:
  /// unknown key (allowed here: a, b, ...)" for the first such key.
  void finish() const {
    for (auto it = j_.begin(); it != j_.end(); ++it) {
      if (seen_.count(it.key())) continue;
      std::string list;
      for (const auto& s : seen_) list += (list.empty() ? "" : ", ") + s;
      json_fail(file_, ptr(it.key()), "unknown key (allowed here: " + list + ")");
    }
  }

  /// `v` as the errors print it (ostream's default: 6 significant digits, "1e+06").
  static std::string num(double v) {
    std::ostringstream os;
    os << v;
    return os.str();
  }
  /// The interval lo..hi as the errors print it: "(" or "[" by `lo_open`, ")" or "]" by `hi_open`,
  /// an infinite bound as "inf" / "-inf", e.g. "(0, 180]".
  static std::string range_text(double lo, double hi, bool lo_open, bool hi_open) {
    auto s = [](double v) { return std::isinf(v) ? (v > 0 ? std::string("inf") : std::string("-inf")) : num(v); };
    return std::string(lo_open ? "(" : "[") + s(lo) + ", " + s(hi) + (hi_open ? ")" : "]");
  }

 private:
  const json& j_;
  std::string file_, ptr_;
  std::set<std::string> seen_;
};

}  // namespace rayscan::io
