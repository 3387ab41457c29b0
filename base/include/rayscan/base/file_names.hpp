// Extension rules for file names: the one case-insensitive extension test and the one wording of
// "expected a file name ending in ..." used by every reader, writer and job.
#pragma once

#include <filesystem>
#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

namespace rayscan {

/// The extension of `path` in lower case, with the dot (".las"); "" when there is none.
/// ASCII case folding only (file systems differ in their Unicode rules).
[[nodiscard]] std::string lower_extension(const std::filesystem::path& path);

/// True when lower_extension(path) equals one of `extensions` (each lower case, with the dot).
[[nodiscard]] bool has_extension(const std::filesystem::path& path, const std::vector<std::string>& extensions);

/// "expected a file name ending in .a, .b or .c" for the given extensions (in their order).
[[nodiscard]] std::string extensions_expected(const std::vector<std::string>& extensions);

}  // namespace rayscan
