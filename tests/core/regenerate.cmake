# Runs the table generator and compares its output with the committed table.
execute_process(COMMAND ${GEN} ${OUT} RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the generator failed (${rc})")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${OUT} ${REF} RESULT_VARIABLE same)
if(NOT same EQUAL 0)
  message(FATAL_ERROR "libcore/src/mc_tables.inc differs from the generator's output: "
                      "regenerate it with isomend_gentables")
endif()
message(STATUS "mc_tables.inc matches the generator")
