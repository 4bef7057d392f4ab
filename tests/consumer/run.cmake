# CTest driver of the consumer test: installs BUILD_DIR into a fresh PREFIX, configures and
# builds tests/consumer against it (only find_package, no source tree), and runs it.
# With PYTHON, the installed Python package is imported and used from the prefix too.
#   cmake -DBUILD_DIR=... -DSOURCE_DIR=... -DWORK_DIR=... [-DLAUNCHER=ccache] [-DPYTHON=...] -P run.cmake
file(REMOVE_RECURSE ${WORK_DIR})
set(prefix ${WORK_DIR}/prefix)
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "consumer: failed (${rc}): ${ARGN}")
  endif()
endfunction()
run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix})
# Relocatable: the consumer sees the prefix under another name than the one installed to.
file(RENAME ${prefix} ${WORK_DIR}/moved)
set(prefix ${WORK_DIR}/moved)
set(extra)
if(LAUNCHER)
  list(APPEND extra -DCMAKE_CXX_COMPILER_LAUNCHER=${LAUNCHER})
endif()
run(${CMAKE_COMMAND} -S ${SOURCE_DIR}/tests/consumer -B ${WORK_DIR}/build -G Ninja
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH=${prefix} ${extra})
run(${CMAKE_COMMAND} --build ${WORK_DIR}/build)
run(${WORK_DIR}/build/consumer ${WORK_DIR}/box.vtu)
if(EXISTS ${prefix}/bin/incise)
  run(${prefix}/bin/incise --help)
  # The viewer's page is installed and the moved prefix's incise finds its own copy.
  if(EXISTS ${prefix}/share/incise/web/viewer.js)
    execute_process(COMMAND ${prefix}/bin/incise view --help OUTPUT_VARIABLE view_help RESULT_VARIABLE rc)
    string(FIND "${view_help}" "${prefix}/share/incise/web" at)
    if(NOT rc EQUAL 0 OR at EQUAL -1)
      message(FATAL_ERROR "consumer: the installed incise view does not serve ${prefix}/share/incise/web:\n${view_help}")
    endif()
  endif()
else()
  message(FATAL_ERROR "consumer: ${prefix}/bin/incise was not installed")
endif()
if(PYTHON)
  run(${CMAKE_COMMAND} -E env PYTHONPATH=${prefix}/lib/python3/dist-packages ${PYTHON}
      ${SOURCE_DIR}/tests/consumer/use_incise.py ${prefix}/lib/python3/dist-packages)
endif()
