# Runs two programs (each with its arguments, a list) and requires their
# standard output to be identical (the schedules of isomend_extract():
# tests/core/test_digest.c as it is and with a schedule), or runs one and
# requires its output to be a file's (core_digest_expected).
#   cmake -DA=PROGRAM_A [-DA_ARGS=...] -DB=PROGRAM_B [-DB_ARGS=...] -P compare_outputs.cmake
#   cmake -DA=PROGRAM_A [-DA_ARGS=...] -DEXPECTED=FILE -P compare_outputs.cmake
set(programs A B)
if(DEFINED EXPECTED)
  set(programs A)
  file(READ ${EXPECTED} out_B)
  set(B ${EXPECTED})
endif()
foreach(p ${programs})
  execute_process(COMMAND ${${p}} ${${p}_ARGS} OUTPUT_VARIABLE out_${p} RESULT_VARIABLE rc_${p})
  if(NOT rc_${p} EQUAL 0)
    message(FATAL_ERROR "${${p}} exited with ${rc_${p}}:\n${out_${p}}")
  endif()
endforeach()
message("${out_A}")
if(NOT out_A STREQUAL out_B)
  message(FATAL_ERROR "the outputs differ; ${B} printed:\n${out_B}")
endif()
string(REGEX MATCHALL "\n" lines "${out_A}")
list(LENGTH lines n)
message("identical: ${n} meshes")
