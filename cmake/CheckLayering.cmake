# The layering rules, checked over the sources (RULE selects one; ROOT is the repository):
#   runtime  runtime/ includes no hardware header (V4L2, libcamera, libgpiod, media controller,
#            DRM, FFmpeg) and nothing from hal/: the core stays portable.
#   tools    nothing outside tools/ includes tools/, but the tests of the executables
#            (tests/tools/, and the fuzz target of mocapd's configuration,
#            tests/fuzz/fuzz_config_json.cpp): the executables compose runtime/ and hal/, never
#            the reverse.
#   opencv   OpenCV (the board calibration's detection and calibrateCamera) is included under
#            runtime/boardcal/ only: it never reaches the real-time path.
if(RULE STREQUAL "runtime")
  file(GLOB_RECURSE files "${ROOT}/runtime/*.h" "${ROOT}/runtime/*.hpp" "${ROOT}/runtime/*.cpp"
       "${ROOT}/runtime/*.cc")
  set(regex "(linux/|libcamera/|gpiod|media/|drm/|sys/ioctl|asm/|libav|libsw|hal/)")
  set(what "hardware headers included under runtime/")
elseif(RULE STREQUAL "tools")
  file(GLOB_RECURSE files "${ROOT}/runtime/*.h" "${ROOT}/runtime/*.cpp" "${ROOT}/hal/*.h"
       "${ROOT}/hal/*.cpp" "${ROOT}/tests/*.h" "${ROOT}/tests/*.cpp")
  list(FILTER files EXCLUDE REGEX "^${ROOT}/tests/tools/")
  list(FILTER files EXCLUDE REGEX "^${ROOT}/tests/fuzz/fuzz_config_json\\.cpp$")
  set(regex "tools/")
  set(what "tools/ included from outside tools/")
elseif(RULE STREQUAL "opencv")
  file(GLOB_RECURSE files "${ROOT}/runtime/*.h" "${ROOT}/runtime/*.cpp" "${ROOT}/hal/*.h"
       "${ROOT}/hal/*.cpp" "${ROOT}/tools/*.h" "${ROOT}/tools/*.cpp")
  list(FILTER files EXCLUDE REGEX "^${ROOT}/runtime/boardcal/")
  list(FILTER files EXCLUDE REGEX "/node_modules/")
  set(regex "opencv")
  set(what "OpenCV included outside runtime/boardcal/")
else()
  message(FATAL_ERROR "RULE must be runtime, tools or opencv, got '${RULE}'")
endif()
set(bad "")
foreach(f IN LISTS files)
  file(STRINGS "${f}" lines REGEX "^[ \t]*#[ \t]*include[ \t]*[<\"]${regex}")
  if(lines)
    list(APPEND bad "${f}: ${lines}")
  endif()
endforeach()
list(LENGTH files n)
if(n EQUAL 0)
  message(FATAL_ERROR "layering check (${RULE}) found no sources under ${ROOT}")
endif()
if(bad)
  string(REPLACE ";" "\n" bad "${bad}")
  message(FATAL_ERROR "${what}:\n${bad}")
endif()
message(STATUS "layering (${RULE}): ${n} files, no forbidden include")
