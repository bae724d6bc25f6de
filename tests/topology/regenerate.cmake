# Runs the method table generator and compares its output with the
# committed libcore/src/methods_tables.inc.
execute_process(COMMAND ${GEN} ${OUT} RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "isomend_genmethods failed (${rc})")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${OUT} ${REF} RESULT_VARIABLE same)
if(NOT same EQUAL 0)
  message(FATAL_ERROR "libcore/src/methods_tables.inc differs from the generator's output: "
                      "regenerate it with isomend_genmethods libcore/src/methods_tables.inc")
endif()
message(STATUS "methods_tables.inc matches the generator")
