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
  add_compile_options(-fsanitize=thread -fno-omit-frame-pointer)
  add_link_options(-fsanitize=thread)
endif()
