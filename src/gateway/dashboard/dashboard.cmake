# Included by src/gateway/CMakeLists.txt. The gateway's web dashboard (docs/DESIGN.md, gateway): the files in web/ and uPlot's dist
# files from npm (package.json at the top of the repository) are embedded into the program at
# build time, so the dashboard works offline and the gateway needs no files beside it.
# LOOPWIRE_DASHBOARD=OFF builds a gateway without it (dashboard_assets_placeholder.cpp: a page
# pointing at the API), for a machine without npm. Fuzz builds (which drive the HTTP front, not
# the dashboard's files) always take the placeholder.
option(LOOPWIRE_DASHBOARD "Embed the web dashboard (needs uPlot from npm: scripts/setup runs npm ci)" ON)
if(NOT LOOPWIRE_DASHBOARD OR LOOPWIRE_FUZZ)
  set(LOOPWIRE_DASHBOARD_SOURCE ${CMAKE_CURRENT_LIST_DIR}/../dashboard_assets_placeholder.cpp)
  return()
endif()
set(dashboard_web ${CMAKE_CURRENT_LIST_DIR}/web)
set(uplot_dist ${PROJECT_SOURCE_DIR}/node_modules/uplot/dist)
if(NOT EXISTS ${uplot_dist}/uPlot.iife.min.js OR NOT EXISTS ${uplot_dist}/uPlot.min.css)
  message(FATAL_ERROR "The dashboard embeds uPlot from ${PROJECT_SOURCE_DIR}/node_modules, which is missing: "
    "run scripts/setup (or `npm ci` in ${PROJECT_SOURCE_DIR}) and configure again, or configure with "
    "-DLOOPWIRE_DASHBOARD=OFF for a gateway without its dashboard")
endif()

# URL path = file; "/" is served as /index.html, everything else lives under /assets/.
set(dashboard_assets /index.html=${dashboard_web}/index.html)
set(dashboard_files ${dashboard_web}/index.html)
foreach(file app.js api.js store.js format.js keys.js ui.js overview.js device.js changes.js trend.js app.css favicon.svg)
  list(APPEND dashboard_assets /assets/${file}=${dashboard_web}/${file})
  list(APPEND dashboard_files ${dashboard_web}/${file})
endforeach()
foreach(file uPlot.iife.min.js uPlot.min.css)
  list(APPEND dashboard_assets /assets/vendor/${file}=${uplot_dist}/${file})
  list(APPEND dashboard_files ${uplot_dist}/${file})
endforeach()

set(dashboard_source ${CMAKE_CURRENT_BINARY_DIR}/dashboard_assets.cpp)
add_custom_command(
  OUTPUT ${dashboard_source}
  COMMAND ${CMAKE_COMMAND} "-DASSETS=${dashboard_assets}" -DOUTPUT=${dashboard_source}
          -P ${CMAKE_CURRENT_LIST_DIR}/embed_dashboard.cmake
  DEPENDS ${dashboard_files} ${CMAKE_CURRENT_LIST_DIR}/embed_dashboard.cmake
  COMMENT "Embedding the dashboard (src/gateway/dashboard/web, uPlot) into loopwire_gateway"
  VERBATIM)
# Compiled into loopwire_gateway in place of dashboard_assets_placeholder.cpp.
set(LOOPWIRE_DASHBOARD_SOURCE ${dashboard_source})
# Clang wants string literals under 65,536 characters (-Woverlength-strings under -Wpedantic);
# uPlot's minified script is longer. GCC does not apply the limit to C++.
if(CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
  set_source_files_properties(${dashboard_source} PROPERTIES COMPILE_OPTIONS "-Wno-overlength-strings")
endif()
