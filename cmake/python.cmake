# Finds pybind11 for Debian's interpreter (/usr/bin/python3, where python3-numpy lives; a
# `python3` earlier on PATH may be another one) and sets INCISE_HAVE_PYTHON. The static
# libraries become position independent so the extension module can link them.
set(INCISE_PYTHON_EXECUTABLE /usr/bin/python3 CACHE FILEPATH "Interpreter the Python module is built for")
set(PYTHON_EXECUTABLE ${INCISE_PYTHON_EXECUTABLE} CACHE FILEPATH "" FORCE)
# The headers first: pybind11's own search stops the configure when they are missing.
set(Python3_EXECUTABLE ${INCISE_PYTHON_EXECUTABLE})
find_package(Python3 QUIET COMPONENTS Interpreter Development.Module)
if(Python3_Development.Module_FOUND)
  find_package(pybind11 CONFIG QUIET)
endif()
if(pybind11_FOUND)
  set(INCISE_HAVE_PYTHON ON)
  set(CMAKE_POSITION_INDEPENDENT_CODE ON)
  message(STATUS "incise: Python module for ${PYTHON_EXECUTABLE} (pybind11 ${pybind11_VERSION})")
else()
  set(INCISE_HAVE_PYTHON OFF)
  message(STATUS "incise: pybind11 not found, no Python module (apt-get install pybind11-dev python3-dev)")
endif()
