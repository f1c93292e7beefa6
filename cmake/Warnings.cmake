# Warnings as errors for every project target (third-party headers come in as SYSTEM).
add_library(mocap_warnings INTERFACE)
target_compile_options(mocap_warnings INTERFACE
  -Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor -Wold-style-cast -Wcast-align
  -Wunused -Woverloaded-virtual -Wnull-dereference -Wdouble-promotion -Wformat=2
  -Wimplicit-fallthrough -Werror
  # clang: the Vulkan structs' `VkFoo x{VK_STRUCTURE_TYPE_FOO}` idiom (runtime/gpu, whose
  # headers tests include too), and clang before 18 also warns about the members a designated
  # initializer leaves out; last, because clang honours the later of this and -Wextra.
  $<$<CXX_COMPILER_ID:Clang>:-Wno-missing-field-initializers>)
