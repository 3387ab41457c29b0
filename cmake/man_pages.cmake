# Man pages: rayscan(1) and one page per subcommand (rayscan-render(1), rayscan-db-import(1), ...),
# generated at build time by help2man from the CLI's own --help, so they never drift from it.
# Written to <build>/man/man1 (`MANPATH=build/man man rayscan-render` from the build tree) and
# installed to ${CMAKE_INSTALL_MANDIR}/man1 (`man rayscan-render` after `cmake --install`).
# Included from tools/CMakeLists.txt after the `rayscan` target. help2man is a Debian package that
# tools/install-deps.sh installs; without it the pages are skipped with a message.
include(GNUInstallDirs)
option(RAYSCAN_MAN_PAGES "Generate the man pages with help2man" ON)
set_property(GLOBAL PROPERTY RAYSCAN_MAN_PAGE_FILES "")
if(NOT RAYSCAN_MAN_PAGES)
  return()
endif()
find_program(HELP2MAN_EXECUTABLE help2man)
if(NOT HELP2MAN_EXECUTABLE)
  message(STATUS "help2man not found: the man pages are not generated (install the Debian package "
                 "help2man, e.g. with tools/install-deps.sh, or configure with -DRAYSCAN_MAN_PAGES=OFF)")
  return()
endif()

# Subcommand (words joined by "-") and the one-line description of its NAME section (no ";":
# this is a CMake list).
set(rayscan_man_names
  "|ray queries, rendering and visibility analysis on raw point clouds"
  "query|ray queries on a point cloud: k nearest to a ray, radius, first sphere hit"
  "render|path-trace a point cloud or scene, write an orthophoto and DSM GeoTIFF"
  "info|describe a point cloud or index file"
  "compare|compare an image with a reference image"
  "visibility|viewshed, per-point visibility, sky view factor"
  "solar|irradiation and shadows on a point cloud, with the points' own shadows"
  "solar-position|sun position, sunrise and sunset (NREL SPA)"
  "db|database commands"
  "db-import|import point clouds into SQLite or PostgreSQL for the SQL ray functions"
  "index|build an out-of-core index file (.rsi) of a site"
  "translate|convert point cloud files"
  "version|print the version, commit, SIMD path and library versions")

set(man_dir ${CMAKE_BINARY_DIR}/man/man1)
set(man_bin ${CMAKE_CURRENT_BINARY_DIR}/man_wrappers)
set(man_gz_dir ${CMAKE_BINARY_DIR}/man-gz/man1)
set(man_pages "")
set(man_pages_gz "")
foreach(entry ${rayscan_man_names})
  string(FIND "${entry}" "|" bar)
  string(SUBSTRING "${entry}" 0 ${bar} sub)
  math(EXPR bar "${bar} + 1")
  string(SUBSTRING "${entry}" ${bar} -1 what)
  if(sub STREQUAL "")
    set(page rayscan)
    set(args "")
  else()
    set(page rayscan-${sub})
    string(REPLACE "-" " " args "${sub}")
  endif()
  # help2man names the page after the executable it runs: a wrapper per subcommand, which passes
  # argv[0] = "rayscan" so that the synopsis reads "rayscan render [OPTIONS] ...".
  file(GENERATE OUTPUT ${man_bin}/${page}
    CONTENT "#!/bin/bash\nexec -a rayscan \"$<TARGET_FILE:rayscan>\" ${args} \"$@\"\n"
    FILE_PERMISSIONS OWNER_READ OWNER_WRITE OWNER_EXECUTE GROUP_READ GROUP_EXECUTE WORLD_READ WORLD_EXECUTE)
  # SEE ALSO: the command's siblings and the documentation.
  if(page STREQUAL "rayscan")
    set(see_also "rayscan-query(1), rayscan-render(1), rayscan-info(1), rayscan-compare(1), rayscan-visibility(1), rayscan-solar(1), rayscan-solar-position(1), rayscan-db-import(1), rayscan-index(1), rayscan-translate(1), rayscan-version(1)")
  else()
    set(see_also "rayscan(1)")
  endif()
  file(CONFIGURE OUTPUT ${man_bin}/${page}.h2m CONTENT
    "[SEE ALSO]\n${see_also}\n.PP\nThe user's manual: README.md and docs/ (docs/cli.md, docs/rendering.md, docs/visibility.md, docs/solar.md, docs/sql.md, docs/python.md) in the rayscan sources.\n")
  add_custom_command(OUTPUT ${man_dir}/${page}.1
    COMMAND ${CMAKE_COMMAND} -E make_directory ${man_dir}
    COMMAND ${CMAKE_COMMAND} -E env ASAN_OPTIONS=detect_leaks=0  # a sanitizer build's --help
            ${HELP2MAN_EXECUTABLE} --no-info --section=1 --version-string=${PROJECT_VERSION}
            "--name=${what}" "--source=rayscan ${PROJECT_VERSION}" "--manual=rayscan manual"
            --include=${man_bin}/${page}.h2m --output=${man_dir}/${page}.1 ${man_bin}/${page}
    DEPENDS rayscan ${man_bin}/${page}.h2m
    COMMENT "help2man: ${page}.1" VERBATIM)
  # Installed compressed, as Debian's policy (section 12.1) asks: gzip -9n, reproducible.
  add_custom_command(OUTPUT ${man_gz_dir}/${page}.1.gz
    COMMAND ${CMAKE_COMMAND} -E make_directory ${man_gz_dir}
    COMMAND sh -c "gzip -9nc '${man_dir}/${page}.1' > '${man_gz_dir}/${page}.1.gz'"
    DEPENDS ${man_dir}/${page}.1 VERBATIM)
  list(APPEND man_pages ${man_dir}/${page}.1)
  list(APPEND man_pages_gz ${man_gz_dir}/${page}.1.gz)
endforeach()
add_custom_target(rayscan_man_pages ALL DEPENDS ${man_pages} ${man_pages_gz})
install(FILES ${man_pages_gz} DESTINATION ${CMAKE_INSTALL_MANDIR}/man1 COMPONENT cli)
set_property(GLOBAL PROPERTY RAYSCAN_MAN_PAGE_FILES "${man_pages}")
