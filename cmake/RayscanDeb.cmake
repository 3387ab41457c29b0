# The Debian packages of rayscan, built by `cpack -G DEB` in a configured build folder
# (tools/package.sh does it, from the same Release build the tests use). Each install component is
# one package, laid out as Debian's own packages are:
#
# | component    | package                 | holds                                                   |
# |--------------|-------------------------|---------------------------------------------------------|
# | `cli`        | `rayscan`               | /usr/bin/rayscan, man pages, /usr/lib/rayscan/ (the OpenImageIO module) |
# | `dev`        | `librayscan-dev`        | headers, the static libraries, the CMake package        |
# | `python`     | `python3-rayscan`       | /usr/lib/python3/dist-packages/rayscan                  |
# | `sqlite`     | `libsqlite3-mod-rayscan`| /usr/lib/rayscan_sqlite.so (`.load rayscan_sqlite`)     |
# | `postgresql` | `postgresql-15-rayscan` | the extension in pg_config's directories (the prefix /usr is PostgreSQL's) |
# | `qgis`       | `qgis-plugin-rayscan`   | the Processing plugin in /usr/share/qgis/python/plugins |
#
# Dependencies on shared libraries are computed by dpkg-shlibdeps (CPACK_DEBIAN_PACKAGE_SHLIBDEPS);
# the others (python3-numpy, postgresql-15, the -dev packages a consumer of the static libraries
# links) are named below. The version is the project's (project() in CMakeLists.txt) with Debian
# revision 1; the top entry of cmake/debian/changelog must name the same version (checked here).
# Every package carries /usr/share/doc/<package>/copyright and changelog.Debian.gz (Debian policy
# sections 12.5 and 12.7).

set(RAYSCAN_DEB_REVISION 1)
set(rayscan_deb_version ${PROJECT_VERSION}-${RAYSCAN_DEB_REVISION})

# The changelog's top entry names the version being packaged.
file(STRINGS ${PROJECT_SOURCE_DIR}/cmake/debian/changelog rayscan_changelog_top LIMIT_COUNT 1)
if(NOT rayscan_changelog_top MATCHES "^rayscan \\(${rayscan_deb_version}\\) ")
  message(FATAL_ERROR "cmake/debian/changelog: the top entry is '${rayscan_changelog_top}', expected "
                      "version ${rayscan_deb_version} (the project version ${PROJECT_VERSION}, revision "
                      "${RAYSCAN_DEB_REVISION}): add an entry for it")
endif()
set_property(DIRECTORY APPEND PROPERTY CMAKE_CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/cmake/debian/changelog)
# Compressed as the policy asks, reproducibly (gzip -n: no name, no time stamp).
set(rayscan_changelog_gz ${PROJECT_BINARY_DIR}/debian/changelog.Debian.gz)
file(MAKE_DIRECTORY ${PROJECT_BINARY_DIR}/debian)
execute_process(COMMAND gzip -9nc ${PROJECT_SOURCE_DIR}/cmake/debian/changelog
                OUTPUT_FILE ${rayscan_changelog_gz} RESULT_VARIABLE rayscan_gzip_rc)
if(NOT rayscan_gzip_rc EQUAL 0)
  message(FATAL_ERROR "gzip of cmake/debian/changelog failed (${rayscan_gzip_rc})")
endif()

# component -> package name, section, summary line, extra dependencies.
set(rayscan_deb_components cli dev python sqlite postgresql)
if(TARGET rayscan_qgis_plugin)
  list(APPEND rayscan_deb_components qgis)
endif()
set(pkg_cli rayscan)
set(pkg_dev librayscan-dev)
set(pkg_python python3-rayscan)
set(pkg_sqlite libsqlite3-mod-rayscan)
set(pkg_postgresql postgresql-15-rayscan)
set(pkg_qgis qgis-plugin-rayscan)

set(section_cli science)
set(section_dev libdevel)
set(section_python python)
set(section_sqlite libs)
set(section_postgresql database)
set(section_qgis science)

set(summary_cli "ray queries, rendering and visibility on raw point clouds (LAS/LAZ/COPC)")
set(summary_dev "ray queries on raw point clouds - C++ libraries and headers")
set(summary_python "ray queries on raw point clouds - Python 3 module")
set(summary_sqlite "ray queries on raw point clouds - SQLite extension")
set(summary_postgresql "ray queries on raw point clouds - PostgreSQL 15 extension")
set(summary_qgis "ray queries on raw point clouds - QGIS Processing provider")

set(long_cli "rayscan renders scanned sites straight from their points, compares renders
 against reference images, maps visibility, viewsheds, sun and shadow, and answers ray and
 point queries (kNN, radius, box) on an octree of the points, in memory, as an index file or on
 a COPC file's own hierarchy.")
set(long_dev "The static libraries rayscan::base, octree, io, site, camera, image, render,
 analysis and jobs, their headers, and the CMake package: find_package(rayscan).")
set(long_python "import rayscan: point clouds from NumPy arrays, ray and point queries, render,
 visibility, compare and solar jobs, and rayscan.dask for Dask clusters.")
set(long_sqlite "The paper's SQL functions dist_ray and dist_plane with their pruning callbacks
 for SQLite: .load rayscan_sqlite")
set(long_postgresql "The paper's SQL functions dist_ray and dist_plane with bounds evaluation for
 PostgreSQL 15: CREATE EXTENSION rayscan")
set(long_qgis "A Processing provider with rayscan's quick-look render, ortho map and DSM,
 viewshed from a point layer of observers, per-point visibility and solar irradiation.")

set(rayscan_dev_depends "rayscan (= ${rayscan_deb_version}), libglm-dev, libtbb-dev, libgdal-dev, nlohmann-json3-dev, zlib1g-dev")
if(TARGET rayscan_mpi)
  string(APPEND rayscan_dev_depends ", libopenmpi-dev")
endif()
set(depends_cli "")
set(depends_dev "${rayscan_dev_depends}")
set(depends_python "rayscan (= ${rayscan_deb_version}), python3 (>= ${RAYSCAN_PYTHON_VERSION}), python3 (<< ${RAYSCAN_PYTHON_VERSION}.99), python3-numpy")
set(depends_sqlite "")
set(depends_postgresql "postgresql-15")
set(depends_qgis "rayscan (= ${rayscan_deb_version}), qgis, python3-qgis")

foreach(c ${rayscan_deb_components})
  string(TOUPPER ${c} C)
  set(CPACK_DEBIAN_${C}_PACKAGE_NAME ${pkg_${c}})
  set(CPACK_DEBIAN_${C}_PACKAGE_SECTION ${section_${c}})
  set(CPACK_DEBIAN_${C}_DESCRIPTION "${summary_${c}}\n ${long_${c}}")
  if(depends_${c})
    set(CPACK_DEBIAN_${C}_PACKAGE_DEPENDS "${depends_${c}}")
  endif()
  install(FILES ${PROJECT_SOURCE_DIR}/cmake/debian/copyright ${rayscan_changelog_gz}
          DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/doc/${pkg_${c}} COMPONENT ${c})
endforeach()
set(CPACK_DEBIAN_SQLITE_PACKAGE_RECOMMENDS sqlite3)
set(CPACK_DEBIAN_QGIS_PACKAGE_ARCHITECTURE all)
set(CPACK_DEBIAN_DEV_PACKAGE_SHLIBDEPS OFF)  # headers and static archives: nothing to scan

set(CPACK_GENERATOR DEB)
set(CPACK_COMPONENTS_ALL ${rayscan_deb_components})
set(CPACK_DEB_COMPONENT_INSTALL ON)
set(CPACK_PACKAGE_NAME rayscan)
set(CPACK_PACKAGE_VERSION ${PROJECT_VERSION})
set(CPACK_PACKAGE_CONTACT "rayscan maintainers <maintainers@users.noreply.h-seed-493149ec.example>")
set(CPACK_DEBIAN_PACKAGE_RELEASE ${RAYSCAN_DEB_REVISION})
set(CPACK_DEBIAN_FILE_NAME DEB-DEFAULT)  # <package>_<version>-<revision>_<arch>.deb
set(CPACK_DEBIAN_PACKAGE_PRIORITY optional)
set(CPACK_DEBIAN_PACKAGE_SHLIBDEPS ON)
set(CPACK_DEBIAN_COMPRESSION_TYPE xz)
# DESTDIR staging with the real prefix: the install rules see CMAKE_INSTALL_PREFIX=/usr (the Python
# module's destination is chosen from it, python/CMakeLists.txt).
set(CPACK_PACKAGING_INSTALL_PREFIX /usr)
set(CPACK_INSTALL_PREFIX /usr)
set(CPACK_SET_DESTDIR ON)
set(CPACK_STRIP_FILES ON)
set(CPACK_PACKAGE_DIRECTORY ${PROJECT_BINARY_DIR}/packages)
include(CPack)
