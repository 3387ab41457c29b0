# The CMake package of rayscan: `cmake --install build --prefix P` installs the public headers,
# the libraries and P/lib/cmake/rayscan/rayscanConfig.cmake (+ version file) with the targets
# rayscan::base, rayscan::octree, rayscan::io, rayscan::site, rayscan::camera, rayscan::image,
# rayscan::render, rayscan::analysis, rayscan::jobs, and rayscan::mpi (component `mpi`) when built
# with RAYSCAN_MPI.
include(CMakePackageConfigHelpers)

set(RAYSCAN_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/rayscan)

# Install the public headers under `dir` (a folder holding rayscan/...).
function(rayscan_install_headers dir)
  install(DIRECTORY ${dir}/ DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT dev FILES_MATCHING PATTERN "*.hpp")
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
          ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev
          LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT dev
          INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
  install(EXPORT rayscanTargets NAMESPACE rayscan:: DESTINATION ${RAYSCAN_INSTALL_CMAKEDIR} COMPONENT dev)
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
          DESTINATION ${RAYSCAN_INSTALL_CMAKEDIR} COMPONENT dev)
endfunction()

# rayscan_add_library(<room> SOURCES src...): the library rayscan_<room> of a room (docs/
# architecture.md): alias rayscan::<room>, public headers in <room>/include (installed), the
# project's warnings, C++20. The caller adds its dependencies and any unity-build SKIP list.
function(rayscan_add_library room)
  cmake_parse_arguments(L "" "" "SOURCES" ${ARGN})
  add_library(rayscan_${room} ${L_SOURCES})
  add_library(rayscan::${room} ALIAS rayscan_${room})
  set_target_properties(rayscan_${room} PROPERTIES EXPORT_NAME ${room})
  target_include_directories(rayscan_${room} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include> $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_compile_options(rayscan_${room} PRIVATE ${RAYSCAN_WARNINGS})
  target_compile_features(rayscan_${room} PUBLIC cxx_std_20)
  rayscan_install_headers(${CMAKE_CURRENT_SOURCE_DIR}/include)
endfunction()
