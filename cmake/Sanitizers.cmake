# ASan + UBSan for the test build (tools/test.sh --sanitize, CI).
if(MOCAP_SANITIZE)
  add_compile_options(-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
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
  add_compile_options(-fsanitize=thread -fno-omit-frame-pointer -Wno-free-nonheap-object)
  add_link_options(-fsanitize=thread)
endif()
