# Runs two programs and requires their standard output to be identical
# (core_one_pass_identical and the split variants: tests/core/test_digest.c
# built against the shipped library and against a variant).
#   cmake -DA=PROGRAM_A -DB=PROGRAM_B -P compare_outputs.cmake
foreach(p A B)
  execute_process(COMMAND ${${p}} OUTPUT_VARIABLE out_${p} RESULT_VARIABLE rc_${p})
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
