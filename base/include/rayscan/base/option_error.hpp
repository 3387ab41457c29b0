// An invalid option of a job, named by its field so that each front end spells it its own way:
// the CLI as its flag (`raster_value` -> `--raster-value`, tools/option_names.cpp), Python as its
// keyword argument. Library messages thus describe the problem in the library's terms, and the
// flag names live only in tools/.
#pragma once

#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace rayscan {

/// An option named in an OptionError's message: the field of the job's options struct, e.g.
/// "raster_value" of VisibilityJobOptions.
struct OptionName {
  std::string field;
};

/// Shorthand for an OptionName among an OptionError's parts.
inline OptionName option(std::string field) { return OptionName{std::move(field)}; }

/// An invalid option value or combination of options (a std::invalid_argument, so callers that
/// catch those, and Python's ValueError translation, see it unchanged). The message is a sequence
/// of text and option names: what() writes each name as its field ("raster_value 'x': expected
/// count, distance, sky or camera"), spelled(f) writes f(field) instead.
class OptionError : public std::invalid_argument {
 public:
  using Part = std::variant<std::string, OptionName>;

  /// The message from its parts, in order.
  explicit OptionError(std::vector<Part> parts);

  /// The parts of the message.
  [[nodiscard]] const std::vector<Part>& parts() const noexcept { return *parts_; }

  /// The message with each option written as spell(field).
  [[nodiscard]] std::string spelled(const std::function<std::string(std::string_view field)>& spell) const;

 private:
  std::shared_ptr<const std::vector<Part>> parts_;  // shared: copying an exception must not throw
};

}  // namespace rayscan
