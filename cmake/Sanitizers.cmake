# ASan + UBSan for the test build (tools/test.sh --sanitize, CI). tools/test.sh builds the
# sanitizer builds with clang (its Eigen/Ceres files compile about 1.75 times faster here than
# with GCC) at -O1 (ASan's own advice; the test sources are -Og in every build:
# MOCAP_TEST_OPT in tests/CMakeLists.txt). Measured under ASan+UBSan, ccache off: the
# runtime's calib/compare.cpp 75.6 s at -O2, 47.8 at -O1.
# Three UBSan checks are left out of this build, each one covered by ASan or the CPU and each
# costly to compile: null (a null dereference faults, and ASan reports the SEGV with its stack),
# object-size (out-of-bounds accesses are ASan's own red-zone checks) and alignment (x86-64
# does not fault on it; it instruments every member access). Measured under ASan+UBSan at -O1:
# calib/epipolar.cpp 72.5 s -> 45.9, mocapd/daemon.cpp 33.5 -> 23.2, assoc/graph.cpp 7.7 -> 6.7.
if(MOCAP_SANITIZE)
  add_compile_options(-fsanitize=address,undefined -fno-sanitize=alignment,null,object-size
                      -fno-sanitize-recover=all -fno-omit-frame-pointer)
  add_link_options(-fsanitize=address,undefined -fno-sanitize-recover=all)
endif()

# ThreadSanitizer for the threaded tests (tools/test.sh --tsan, CI): label "threads".
if(MOCAP_TSAN)
  if(MOCAP_SANITIZE)
    message(FATAL_ERROR "MOCAP_TSAN and MOCAP_SANITIZE cannot be combined (one build each)")
  endif()
  # GCC 12 under -fsanitize=thread reports std::vector growth as freeing a non-heap pointer
  # (-Wfree-nonheap-object in TriggerMonitor::stats, a plain push_back loop): a known false
  # positive of its instrumented inlining, off in this build only.
  add_compile_options(-fsanitize=thread -fno-omit-frame-pointer)
  if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
    add_compile_options(-Wno-free-nonheap-object)
  endif()
  add_link_options(-fsanitize=thread)
endif()
