# Tests of the FilterPlugin adapter in the installed MeshLab 2021.05+
# (included by CMakeLists.txt; Debian 13's MeshLab 2022.02 in the trixie root
# of scripts/test-trixie.sh).  Label "trixie".

# The harness: MeshLab's own library and plugin loader, no window.
add_executable(meshlab_run_filter meshlab_run_filter.cpp)
set_target_properties(meshlab_run_filter PROPERTIES CXX_STANDARD 17)
target_include_directories(meshlab_run_filter SYSTEM PRIVATE
  "${ISOMEND_MESHLAB_TREE}/src" "${ISOMEND_MESHLAB_TREE}/src/vcglib")
target_compile_definitions(meshlab_run_filter PRIVATE
  MESHLAB_SCALAR=float MESHLAB_VERSION=${ISOMEND_MESHLAB_VERSION})
# (imported targets are scoped to the directory that found them)
find_package(Qt5 COMPONENTS Core Gui Widgets OpenGL Xml REQUIRED)
find_package(OpenGL REQUIRED)
find_package(GLEW REQUIRED)
find_package(Eigen3 NO_MODULE REQUIRED)
target_link_libraries(meshlab_run_filter PRIVATE "${ISOMEND_MESHLAB_COMMON_LIB}"
  Qt5::Core Qt5::Gui Qt5::Widgets Qt5::OpenGL Qt5::Xml GLEW::GLEW OpenGL::GL Eigen3::Eigen)
isomend_warnings(meshlab_run_filter)

get_filename_component(_ml_libdir "${ISOMEND_MESHLAB_COMMON_LIB}" DIRECTORY)
set(_ml_stock "${_ml_libdir}/plugins")
foreach(stock libfilter_measure.so libio_base.so)
  if(NOT EXISTS "${_ml_stock}/${stock}")
    message(STATUS "meshlab2022 tests: skipped (no ${_ml_stock}/${stock})")
    return()
  endif()
endforeach()
if(NOT ISOMEND_PEER_TESTS OR NOT TARGET isomend_cli)
  return()
endif()

set(_harness --harness $<TARGET_FILE:meshlab_run_filter>
  --plugin $<TARGET_FILE:filter_isomend>
  --plugin ${_ml_stock}/libfilter_measure.so --plugin ${_ml_stock}/libio_base.so
  --cli $<TARGET_FILE:isomend_cli>)
foreach(name counts topology holes errors dicom labels)
  add_test(NAME meshlab2022_${name}
    COMMAND ${ISOMEND_PYTHON} ${CMAKE_CURRENT_SOURCE_DIR}/test_meshlab.py ${name} ${_harness}
            --work ${CMAKE_CURRENT_BINARY_DIR}/work2022_${name})
endforeach()
add_test(NAME meshlab2022_methods
  COMMAND ${ISOMEND_PYTHON} ${CMAKE_CURRENT_SOURCE_DIR}/test_meshlab.py methods ${_harness}
          --job $<TARGET_FILE:test_meshlab_job>
          --work ${CMAKE_CURRENT_BINARY_DIR}/work2022_methods)
add_test(NAME meshlab2022_realdata
  COMMAND ${ISOMEND_PYTHON} ${CMAKE_CURRENT_SOURCE_DIR}/test_meshlab.py realdata ${_harness}
          --get-data ${PROJECT_SOURCE_DIR}/scripts/get-test-data.sh
          --work ${CMAKE_CURRENT_BINARY_DIR}/work2022_realdata)
set(_ml2022_tests meshlab2022_counts meshlab2022_topology meshlab2022_holes
  meshlab2022_errors meshlab2022_methods meshlab2022_realdata meshlab2022_labels)
set_tests_properties(${_ml2022_tests} PROPERTIES LABELS "trixie;peer;meshlab" TIMEOUT 300)
# get-test-data.sh unpacks into fixed temporary names: never run two at once.
set_tests_properties(meshlab2022_realdata PROPERTIES TIMEOUT 600 RESOURCE_LOCK isomend_testdata)

# cmake --install puts the plugin where MeshLab loads it, and MeshLab's
# loader accepts that file and runs it.
add_test(NAME meshlab2022_install
  COMMAND bash ${CMAKE_CURRENT_SOURCE_DIR}/test_install.sh ${CMAKE_BINARY_DIR}
          ${ISOMEND_MESHLAB_PLUGIN_DIR} ${CMAKE_INSTALL_FULL_LIBDIR}
          "$<TARGET_FILE_DIR:isomend>:$<TARGET_FILE_DIR:isomend_io>"
          ${CMAKE_CURRENT_BINARY_DIR}/work2022_install
          $<TARGET_FILE:meshlab_run_filter> ${_ml_stock})
set_tests_properties(meshlab2022_install PROPERTIES LABELS "trixie;peer;meshlab" TIMEOUT 300)

# The GUI: MeshLab itself, the plugin in the user's extra-plugins folder.
find_program(ISOMEND_XDOTOOL xdotool)
find_program(ISOMEND_IMPORT import)
if(ISOMEND_MESHLAB_GUI AND ISOMEND_XDOTOOL AND ISOMEND_IMPORT)
  add_test(NAME meshlab2022_gui
    COMMAND ${ISOMEND_PYTHON} ${CMAKE_CURRENT_SOURCE_DIR}/with_xvfb.py
            ${ISOMEND_PYTHON} ${CMAKE_CURRENT_SOURCE_DIR}/test_gui_2022.py
            --meshlab ${ISOMEND_MESHLAB_GUI} --plugin $<TARGET_FILE:filter_isomend>
            --cli $<TARGET_FILE:isomend_cli>
            --work ${CMAKE_CURRENT_BINARY_DIR}/work2022_gui)
  set_tests_properties(meshlab2022_gui PROPERTIES LABELS "trixie;peer;meshlab" TIMEOUT 300
    ENVIRONMENT "ISOMEND_XVFB_SCREEN=1280x1024x24")
else()
  message(STATUS "meshlab2022_gui: skipped (needs meshlab, xdotool and ImageMagick's import)")
endif()
