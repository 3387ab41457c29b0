# The CMake package of rayscan: `cmake --install build --prefix P` installs the public headers,
# the libraries and P/lib/cmake/rayscan/rayscanConfig.cmake (+ version file) with the targets
# rayscan::base, rayscan::octree, rayscan::io, rayscan::site, rayscan::camera, rayscan::image,
# rayscan::render, rayscan::analysis, rayscan::jobs, and rayscan::mpi (component `mpi`) when built
# with RAYSCAN_MPI.
include(CMakePackageConfigHelpers)

set(RAYSCAN_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/rayscan)

# Install the public headers under `dir` (a folder holding rayscan/...).
function(rayscan_install_headers dir)
  install(DIRECTORY ${dir}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} FILES_MATCHING PATTERN "*.hpp")
endfunction()

# Install and export the library targets that exist, then the package files.
function(rayscan_install_package)
  set(targets)
  foreach(t rayscan_base rayscan_octree rayscan_io rayscan_site rayscan_camera rayscan_image rayscan_renderer
           rayscan_analysis rayscan_jobs rayscan_mpi)
    if(TARGET ${t})
      list(APPEND targets ${t})
    endif()
  endforeach()
  install(TARGETS ${targets} EXPORT rayscanTargets
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
          INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
  install(EXPORT rayscanTargets NAMESPACE rayscan:: DESTINATION ${RAYSCAN_INSTALL_CMAKEDIR})
  set(RAYSCAN_PACKAGE_ONLY_CORE ${RAYSCAN_ONLY_CORE})
  set(RAYSCAN_PACKAGE_MPI OFF)
  if(TARGET rayscan_mpi)
    set(RAYSCAN_PACKAGE_MPI ON)
  endif()
  configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/rayscanConfig.cmake.in
                                ${PROJECT_BINARY_DIR}/rayscanConfig.cmake
                                INSTALL_DESTINATION ${RAYSCAN_INSTALL_CMAKEDIR})
  write_basic_package_version_file(${PROJECT_BINARY_DIR}/rayscanConfigVersion.cmake
                                   VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
  install(FILES ${PROJECT_BINARY_DIR}/rayscanConfig.cmake ${PROJECT_BINARY_DIR}/rayscanConfigVersion.cmake
          DESTINATION ${RAYSCAN_INSTALL_CMAKEDIR})
endfunction()
