# Precompiled headers: the standard library, Eigen and JSON headers most sources include, parsed
# once per library instead of once per source (a source that includes Eigen and JSON spends
# about 2.2 s of its compile on them; loading them precompiled takes a fraction of that). Only
# compile time changes: every header is still included where it is used, and a build with
# -DMOCAP_PRECOMPILED_HEADERS=OFF must keep compiling (it is how missing includes show).
option(MOCAP_PRECOMPILED_HEADERS "precompile the common headers of each library" ON)

set(MOCAP_COMMON_HEADERS
    <algorithm> <array> <cmath> <cstddef> <cstdint> <cstdio> <cstring> <filesystem>
    <functional> <limits> <map> <memory> <mutex> <optional> <span> <string> <string_view>
    <system_error> <utility> <vector> <Eigen/Core> <Eigen/Geometry> <nlohmann/json.hpp>)

# mocap_precompile_common_headers(<target> [REUSE_FROM <target built with the same flags>])
# Sources compiled with options of their own that change predefined macros (-fno-math-errno)
# set SKIP_PRECOMPILE_HEADERS: the compiler refuses a header precompiled without them.
function(mocap_precompile_common_headers target)
  cmake_parse_arguments(P "" "REUSE_FROM" "" ${ARGN})
  if(NOT MOCAP_PRECOMPILED_HEADERS)
    return()
  endif()
  if(P_REUSE_FROM)
    target_precompile_headers(${target} REUSE_FROM ${P_REUSE_FROM})
  else()
    target_precompile_headers(${target} PRIVATE ${MOCAP_COMMON_HEADERS})
  endif()
endfunction()
