# What `cmake --install` puts beside the binary for people at a shell: a man page per command
# (share/man/man1/loopwire.1, loopwire-read.1, ...), the configuration file's page
# (share/man/man5/loopwire-gateway.toml.5) and bash and zsh completion. The pages are
# written at build time by the built binary from its own command-line definitions
# (`loopwire __man-pages`, src/app/man_page.cpp), with the examples of README.md and docs/*.md,
# so they never drift from the commands; the completion scripts ask the binary too
# (`loopwire __complete`).
file(GLOB loopwire_doc_pages CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/docs/*.md)
set(loopwire_example_pages ${PROJECT_SOURCE_DIR}/README.md ${loopwire_doc_pages})
set(loopwire_man_dir ${PROJECT_BINARY_DIR}/man)
set(loopwire_man_stamp ${PROJECT_BINARY_DIR}/man_pages.stamp)
add_custom_command(OUTPUT ${loopwire_man_stamp}
  COMMAND ${CMAKE_COMMAND} -E rm -rf ${loopwire_man_dir}
  COMMAND loopwire __man-pages --output-dir ${loopwire_man_dir} --readme ${loopwire_example_pages}
  COMMAND ${CMAKE_COMMAND} -E touch ${loopwire_man_stamp}
  DEPENDS loopwire ${loopwire_example_pages}
  COMMENT "Writing the man pages from loopwire's command-line definitions"
  VERBATIM)
add_custom_target(loopwire_man_pages ALL DEPENDS ${loopwire_man_stamp})

install(DIRECTORY ${loopwire_man_dir}/ DESTINATION ${CMAKE_INSTALL_MANDIR} COMPONENT runtime)
install(FILES ${PROJECT_SOURCE_DIR}/packaging/completion/loopwire.bash
  DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/bash-completion/completions RENAME loopwire COMPONENT runtime)
install(FILES ${PROJECT_SOURCE_DIR}/packaging/completion/_loopwire
  DESTINATION ${CMAKE_INSTALL_DATAROOTDIR}/zsh/site-functions COMPONENT runtime)
