# The OPC UA front (src/gateway/opcua): open62541 1.4, from Debian 13's libopen62541-1.4-dev
# (scripts/setup). Built only where the library is found, so a machine without it still builds
# the gateway, with [opcua] refused by --check as not built in.
find_package(PkgConfig REQUIRED)
pkg_check_modules(OPEN62541 QUIET open62541>=1.4)
# Debian's open62541.pc names mbedTLS by full path after -l (-l/usr/lib/.../libmbedtls.so),
# which no linker takes: link the library itself, which carries its own dependencies.
find_library(OPEN62541_LIBRARY NAMES open62541 HINTS ${OPEN62541_LIBRARY_DIRS})
set(LOOPWIRE_OPCUA_FOUND OFF)
if(OPEN62541_FOUND AND OPEN62541_LIBRARY)
  set(LOOPWIRE_OPCUA_FOUND ON)
endif()
option(LOOPWIRE_OPCUA "Build the gateway's OPC UA front (needs open62541 1.4)" ${LOOPWIRE_OPCUA_FOUND})
if(LOOPWIRE_OPCUA AND NOT LOOPWIRE_OPCUA_FOUND)
  message(FATAL_ERROR "LOOPWIRE_OPCUA is on but open62541 1.4 was not found: run scripts/setup --deps, or -DLOOPWIRE_OPCUA=OFF")
endif()
if(LOOPWIRE_OPCUA)
  target_sources(loopwire_gateway PRIVATE opcua/opcua_server.cpp opcua/opcua_nodes.cpp opcua/opcua_status.cpp)
  target_include_directories(loopwire_gateway SYSTEM PRIVATE ${OPEN62541_INCLUDE_DIRS})
  target_link_libraries(loopwire_gateway PRIVATE ${OPEN62541_LIBRARY})
  target_compile_definitions(loopwire_gateway PRIVATE LOOPWIRE_OPCUA=1)
else()
  target_sources(loopwire_gateway PRIVATE opcua/opcua_absent.cpp)
endif()
