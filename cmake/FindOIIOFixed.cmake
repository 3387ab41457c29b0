# find_package(OpenImageIO) with a fix for Debian 12: its CMake config lists /usr/include/opencv4
# (OpenCV is an optional OIIO dependency, not installed with libopenimageio-dev) as an include
# directory, which makes every consumer fail to configure. Drop include directories that do not
# exist and make the imported targets global so every folder (renderer, analysis, tests, bench)
# sees the fixed targets.
find_package(OpenImageIO REQUIRED)
foreach(_prop INTERFACE_INCLUDE_DIRECTORIES INTERFACE_SYSTEM_INCLUDE_DIRECTORIES)
  get_target_property(_dirs OpenImageIO::OpenImageIO ${_prop})
  if(_dirs)
    set(_kept)
    foreach(_d IN LISTS _dirs)
      if(EXISTS "${_d}" OR _d MATCHES "^\\$<")
        list(APPEND _kept "${_d}")
      endif()
    endforeach()
    set_target_properties(OpenImageIO::OpenImageIO PROPERTIES ${_prop} "${_kept}")
  endif()
endforeach()
set_target_properties(OpenImageIO::OpenImageIO OpenImageIO::OpenImageIO_Util PROPERTIES IMPORTED_GLOBAL TRUE)
set(OIIOFixed_FOUND TRUE)
