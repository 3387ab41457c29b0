# ctest consumer_package / core_only_package: install a rayscan build into a fresh prefix, then
# configure, build and run tests/consumer/ against it. Variables: BUILD_DIR (the build to install),
# SOURCE_DIR (tests/consumer), WORK_DIR, ONLY_CORE, MPI (built with RAYSCAN_MPI), MPIEXEC, GENERATOR,
# CXX_COMPILER, COMPILER_LAUNCHER;
# with CORE_SOURCE (the rayscan source tree) the script first configures and builds that tree with
# -DRAYSCAN_ONLY_CORE=ON (no OpenImageIO, GDAL, nlohmann_json, CLI11) into WORK_DIR/rayscan and
# installs that build instead.
# The install is staged with DESTDIR, so that a rule with an absolute destination would land under
# WORK_DIR/stage too (never in system directories) and be caught: `cmake --install --prefix P` must
# write nothing outside P (the PostgreSQL extension included; RAYSCAN_PG_SYSTEM_DIRS is off).
set(stage ${WORK_DIR}/stage)
set(prefix ${stage}/prefix)
set(build ${WORK_DIR}/build)
file(REMOVE_RECURSE ${stage} ${WORK_DIR}/prefix ${build})
file(MAKE_DIRECTORY ${WORK_DIR})

function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
  message("${out}")
endfunction()

set(launcher)
if(COMPILER_LAUNCHER)
  set(launcher -DCMAKE_CXX_COMPILER_LAUNCHER=${COMPILER_LAUNCHER})
endif()
if(CORE_SOURCE)
  set(BUILD_DIR ${WORK_DIR}/rayscan)
  run(${CMAKE_COMMAND} -S ${CORE_SOURCE} -B ${BUILD_DIR} -G ${GENERATOR} -DCMAKE_BUILD_TYPE=Release
      -DCMAKE_CXX_COMPILER=${CXX_COMPILER} ${launcher} -DRAYSCAN_ONLY_CORE=ON -DRAYSCAN_BUILD_TESTS=OFF
      -DRAYSCAN_BUILD_BENCH=OFF)
  run(${CMAKE_COMMAND} --build ${BUILD_DIR})
  set(ONLY_CORE ON)
  set(MPI OFF)
endif()
if(NOT MPI)
  set(MPI OFF)
endif()
set(ENV{DESTDIR} ${stage})
run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix /prefix)
unset(ENV{DESTDIR})
# Every installed file lies under the prefix (the install manifest lists them without DESTDIR).
file(STRINGS ${BUILD_DIR}/install_manifest.txt manifest)
foreach(f ${manifest})
  if(NOT f MATCHES "^/prefix/")
    message(FATAL_ERROR "cmake --install --prefix /prefix wrote outside the prefix: ${f}")
  endif()
endforeach()
if(NOT ONLY_CORE)
  # `CREATE EXTENSION rayscan` files: PostgreSQL's layout under the prefix (pg_config's folders
  # relative to Debian's /usr).
  execute_process(COMMAND pg_config --pkglibdir OUTPUT_VARIABLE pg_lib OUTPUT_STRIP_TRAILING_WHITESPACE)
  execute_process(COMMAND pg_config --sharedir OUTPUT_VARIABLE pg_share OUTPUT_STRIP_TRAILING_WHITESPACE)
  string(REGEX REPLACE "^/usr/" "" pg_lib ${pg_lib})
  string(REGEX REPLACE "^/usr/" "" pg_share ${pg_share})
  foreach(f ${pg_lib}/rayscan.so ${pg_share}/extension/rayscan.control ${pg_share}/extension/rayscan--0.1.sql
            ${pg_share}/extension/rayscan--0.1--0.2.sql ${pg_share}/extension/rayscan--0.2--0.3.sql
            ${pg_share}/extension/rayscan--0.3--0.4.sql)
    if(NOT EXISTS ${prefix}/${f})
      message(FATAL_ERROR "install lacks the PostgreSQL extension file ${prefix}/${f}")
    endif()
  endforeach()
endif()
set(installed lib/cmake/rayscan/rayscanConfig.cmake lib/cmake/rayscan/rayscanConfigVersion.cmake
    include/rayscan/octree/octree.hpp include/rayscan/base/progress.hpp)
if(NOT ONLY_CORE)
  # rayscan::image's OpenImageIO module, and a header of each library room.
  list(APPEND installed lib/rayscan/librayscan_oiio.so include/rayscan/io/point_io.hpp include/rayscan/site/index_file.hpp
       include/rayscan/camera/camera.hpp include/rayscan/image/aov.hpp include/rayscan/render/scene.hpp
       include/rayscan/analysis/visibility.hpp include/rayscan/jobs/render.hpp)
endif()
foreach(f ${installed})
  if(NOT EXISTS ${prefix}/${f})
    message(FATAL_ERROR "install lacks ${f}")
  endif()
endforeach()
run(${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${build} -G ${GENERATOR} -DCMAKE_BUILD_TYPE=Release
    -DCMAKE_CXX_COMPILER=${CXX_COMPILER} ${launcher} -DCMAKE_PREFIX_PATH=${prefix}
    -DCONSUMER_ONLY_CORE=${ONLY_CORE} -DCONSUMER_MPI=${MPI})
run(${CMAKE_COMMAND} --build ${build})
run(${build}/consumer_query)
if(MPI)
  # rayscan::mpi from the package: alone, then under the real mpirun (loopback, 2 ranks).
  run(${build}/consumer_mpi)
  set(mpirun_args -n 2 --oversubscribe --bind-to none --mca btl self,vader --mca btl_vader_single_copy_mechanism none)
  execute_process(COMMAND id -u OUTPUT_VARIABLE uid OUTPUT_STRIP_TRAILING_WHITESPACE)
  if(uid STREQUAL "0")
    list(APPEND mpirun_args --allow-run-as-root)
  endif()
  run(${MPIEXEC} ${mpirun_args} ${build}/consumer_mpi)
else()
  file(READ ${prefix}/lib/cmake/rayscan/rayscanTargets.cmake targets)
  if(targets MATCHES "rayscan::mpi")
    message(FATAL_ERROR "a package built without RAYSCAN_MPI exports rayscan::mpi")
  endif()
endif()
if(NOT ONLY_CORE)
  set(ENV{RAYSCAN_OIIO_MODULE} ${prefix}/lib/rayscan/librayscan_oiio.so)  # the installed module
  run(${build}/consumer_jobs)
  unset(ENV{RAYSCAN_OIIO_MODULE})
else()
  # A core-only package must not offer the targets that need OpenImageIO or GDAL.
  file(READ ${prefix}/lib/cmake/rayscan/rayscanTargets.cmake targets)
  if(targets MATCHES "rayscan::(io|render|analysis)")
    message(FATAL_ERROR "core-only package exports more than rayscan::octree")
  endif()
endif()
