# `cmake --install BUILD --prefix P` installs:
#   P/bin/incise                          the command line
#   P/lib/libincise_*.a                   the static libraries
#   P/include/incise/{mesh,quality,cut,sim,scene}/...  public headers; the include directory is
#                                         P/include/incise, so consumers write the project's
#                                         own includes ("mesh/tet_mesh.h")
#   P/lib/cmake/incise/                   package config: find_package(incise) gives
#                                         incise::mesh, ::quality, ::cut, ::sim, ::scene (and ::tetra);
#                                         ::sim links ::sim_linalg, ::sim_material, ::sim_springs
#   P/lib/python3/dist-packages/incise/   the Python module (python/CMakeLists.txt)
# Everything is relative to P (relocatable). The static libraries carry their private link
# dependencies (assimp, zlib, CGAL's gmp/mpfr, OpenVDB) as link-only entries; the package
# config finds them, but their headers never reach a consumer.
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(INCISE_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/incise)
set(INCISE_INSTALL_INCLUDEDIR ${CMAKE_INSTALL_INCLUDEDIR}/incise)

set(_incise_targets incise_mesh incise_quality incise_cut incise_sim_linalg incise_sim_material incise_sim_springs incise_sim
    incise_scene incise_warnings)
set(INCISE_PACKAGE_TETRA OFF)
if(TARGET incise_tetra)
  list(APPEND _incise_targets incise_tetra incise_openvdb)
  set(INCISE_PACKAGE_TETRA ON)
endif()
foreach(t IN LISTS _incise_targets)
  string(REPLACE "incise_" "" _name ${t})
  set_target_properties(${t} PROPERTIES EXPORT_NAME ${_name})
endforeach()

if(TARGET incise)
  install(TARGETS incise RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()
install(TARGETS ${_incise_targets} EXPORT inciseTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  INCLUDES DESTINATION ${INCISE_INSTALL_INCLUDEDIR})

# Headers of every library folder (empty folders install nothing). The CGAL-facing headers
# of mesh/tetrahedralize are internal to its .cpp files and stay out, as does the whole
# folder when incise_tetra is not built.
set(_incise_header_excludes PATTERN "c3t3_to_tet_mesh.h" EXCLUDE PATTERN "mesh3_common.h" EXCLUDE)
if(NOT TARGET incise_tetra)
  list(APPEND _incise_header_excludes PATTERN "tetrahedralize" EXCLUDE)
endif()
foreach(dir mesh quality cut sim scene)
  install(DIRECTORY ${PROJECT_SOURCE_DIR}/${dir} DESTINATION ${INCISE_INSTALL_INCLUDEDIR}
    FILES_MATCHING PATTERN "*.h" ${_incise_header_excludes})
endforeach()

install(EXPORT inciseTargets NAMESPACE incise:: DESTINATION ${INCISE_INSTALL_CMAKEDIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/inciseConfig.cmake.in
  ${PROJECT_BINARY_DIR}/inciseConfig.cmake INSTALL_DESTINATION ${INCISE_INSTALL_CMAKEDIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/inciseConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/inciseConfig.cmake ${PROJECT_BINARY_DIR}/inciseConfigVersion.cmake
  DESTINATION ${INCISE_INSTALL_CMAKEDIR})
