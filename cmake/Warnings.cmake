# Warnings as errors for every project target (third-party headers come in as SYSTEM).
add_library(mocap_warnings INTERFACE)
target_compile_options(mocap_warnings INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wold-style-cast -Wcast-align
  -Wunused -Woverloaded-virtual -Wnull-dereference -Wdouble-promotion -Wformat=2
  -Wimplicit-fallthrough -Werror)
