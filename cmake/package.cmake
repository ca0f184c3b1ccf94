# What `cmake --install` puts in the prefix: the `loopwire` binary, the public headers, one
# static library `libloopwire.a` and the CMake package, so that a program says
#   find_package(loopwire REQUIRED)
#   target_link_libraries(app PRIVATE loopwire::loopwire)
include(GNUInstallDirs)
include(CMakePackageConfigHelpers)

# One library made of every layer's objects, so users link one target whatever the layer
# libraries become. Built from the same objects as the layers: nothing is compiled twice.
set(loopwire_layer_libraries loopwire_common loopwire_codec loopwire_transport loopwire_session
  loopwire_profile loopwire_client loopwire_simulation loopwire_devices loopwire_api)
set(loopwire_layer_objects)
foreach(layer IN LISTS loopwire_layer_libraries)
  list(APPEND loopwire_layer_objects $<TARGET_OBJECTS:${layer}>)
endforeach()
add_library(loopwire_library STATIC ${loopwire_layer_objects})
add_library(loopwire::loopwire ALIAS loopwire_library)
set_target_properties(loopwire_library PROPERTIES OUTPUT_NAME loopwire EXPORT_NAME loopwire LINKER_LANGUAGE CXX)
target_include_directories(loopwire_library INTERFACE
  $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/include>
  $<BUILD_INTERFACE:${PROJECT_BINARY_DIR}/include>
  $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
target_compile_features(loopwire_library INTERFACE cxx_std_17)
# What a static library's users must link besides it. nlohmann-json, Boost.Asio and valijson
# are header-only and used inside loopwire only, so they are not asked of users.
target_link_libraries(loopwire_library INTERFACE fmt::fmt Threads::Threads)
# A sanitized build's objects need the sanitizer runtimes in every program linking them, and
# those of an ASan build, compiled without -fpie (CMakeLists.txt), a program that is not a PIE.
if(LOOPWIRE_SANITIZE)
  target_link_options(loopwire_library INTERFACE -fsanitize=address,undefined -no-pie)
elseif(LOOPWIRE_TSAN)
  target_link_options(loopwire_library INTERFACE -fsanitize=thread)
endif()

# Two components: `runtime` (the binary, its man pages and completion: what scripts/package puts
# in the Debian package) and `development` (the library, headers and CMake package). A plain
# `cmake --install` installs both.
install(TARGETS loopwire RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR} COMPONENT runtime)
install(TARGETS loopwire_library EXPORT loopwireTargets ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR} COMPONENT development)
install(DIRECTORY ${PROJECT_SOURCE_DIR}/include/loopwire DESTINATION ${CMAKE_INSTALL_INCLUDEDIR} COMPONENT development)
install(FILES ${PROJECT_BINARY_DIR}/include/loopwire/version.hpp DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/loopwire
  COMPONENT development)

set(loopwire_package_dir ${CMAKE_INSTALL_LIBDIR}/cmake/loopwire)
install(EXPORT loopwireTargets NAMESPACE loopwire:: DESTINATION ${loopwire_package_dir} COMPONENT development)
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/loopwireConfig.cmake.in
  ${PROJECT_BINARY_DIR}/loopwireConfig.cmake INSTALL_DESTINATION ${loopwire_package_dir})
# Before 1.0 a minor version may change the API: only the same MAJOR.MINOR is compatible.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/loopwireConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/loopwireConfig.cmake ${PROJECT_BINARY_DIR}/loopwireConfigVersion.cmake
  DESTINATION ${loopwire_package_dir} COMPONENT development)

include(${CMAKE_CURRENT_LIST_DIR}/man_pages_and_completion.cmake)
