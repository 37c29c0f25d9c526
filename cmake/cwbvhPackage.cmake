# Install rules and the CMake package: find_package(cwbvh) gives
#   cwbvh::cwbvh_format, cwbvh::cwbvh_loader, cwbvh::cwbvh_cpu_trace,
#   cwbvh::cwbvh_gpu_trace (GPU entry, stub without CUDA) and, when built with CUDA,
#   cwbvh::cwbvh_cuda (kernels, DeviceScene, C API cwbvh_device_upload).
# Included at the end of the top-level CMakeLists.txt (targets from every directory).
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

set(_cwbvh_export_targets)
foreach(t cwbvh_warnings cwbvh_format_headers cwbvh_format cwbvh_loader cwbvh_kernels_headers cwbvh_cpu_trace
          cwbvh_cuda cwbvh_gpu_trace)
  if(TARGET ${t})
    list(APPEND _cwbvh_export_targets ${t})
  endif()
endforeach()

install(TARGETS ${_cwbvh_export_targets} EXPORT cwbvhTargets
  ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
  LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
  RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR}
  INCLUDES DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})
foreach(t cwbvh cwbvhc minimal_render cwbvh_gpu_check)
  if(TARGET ${t})
    install(TARGETS ${t} RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
  endif()
endforeach()
install(DIRECTORY ${PROJECT_SOURCE_DIR}/format/include/cwbvh ${PROJECT_SOURCE_DIR}/loader/include/cwbvh
                  ${PROJECT_SOURCE_DIR}/kernels/include/cwbvh
        DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})

install(EXPORT cwbvhTargets NAMESPACE cwbvh:: DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/cwbvh)
set(CWBVH_PACKAGE_HAVE_CUDA ${CWBVH_HAVE_CUDA})
configure_package_config_file(${CMAKE_CURRENT_LIST_DIR}/cwbvhConfig.cmake.in
  ${CMAKE_CURRENT_BINARY_DIR}/cwbvhConfig.cmake INSTALL_DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/cwbvh)
write_basic_package_version_file(${CMAKE_CURRENT_BINARY_DIR}/cwbvhConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMajorVersion)
install(FILES ${CMAKE_CURRENT_BINARY_DIR}/cwbvhConfig.cmake ${CMAKE_CURRENT_BINARY_DIR}/cwbvhConfigVersion.cmake
        DESTINATION ${CMAKE_INSTALL_LIBDIR}/cmake/cwbvh)
