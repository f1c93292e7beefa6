# The layers of runtime/, lowest first: "<area>:<the areas it may include>". An area may use
# only areas declared above it (CheckLayering.cmake RULE=areas fails otherwise), so adding an
# include that points up the stack fails the `layering.areas` test. docs/architecture.md draws
# the same table.
set(runtime_areas
    # foundations: error handling, logging, files, the skeleton, cameras, images, messages
    "core"
    "skeleton:core"
    "geometry:core"
    "image:core"
    "msg:core,skeleton"
    # the solver: skeleton fitting, the 4D association, calibration from people and boards
    "fit:core,geometry,skeleton"
    "assoc:core,fit,geometry,msg,skeleton"
    "calib:core,fit,geometry,image,msg,skeleton"
    "boardcal:calib,core,geometry,image,msg"
    # the detector's network reader and CPU reference
    "nn:core,msg,skeleton"
    # the real-time pipeline (no network: the stream sink lives in net/)
    "pipeline:assoc,core,msg"
    # the detector's 3D-guided crops, and the Vulkan detector (a pipeline::Detector)
    "crops:core,geometry,msg,skeleton"
    "gpu:core,crops,geometry,msg,nn,pipeline,skeleton"
    "fusion:core,msg"
    "sim:core,geometry,msg,pipeline,skeleton"
    # the stream and status servers, and the pipeline sink that feeds them
    "net:core,msg,pipeline"
    "out:core,msg,skeleton"
    # benchmarks and evaluation (the Shelf files, the metrics), linked by `mocap` and the tests
    "io:core,msg,skeleton"
    "eval:assoc,core,fit,geometry,io,msg,pipeline,skeleton"
    "dds:core,fusion,msg,pipeline,skeleton"
    # the appliance: calibration lifecycle, status, outputs, takes
    "box:assoc,calib,core,geometry,image,msg,net,nn,out,pipeline,skeleton"
    # model tools: the TF.js importer and where the npm package's graphs are cut
    "nn_import:core,nn")

# The libraries the areas are built into, lowest first: "<library>:<its areas>". A library
# links (PUBLIC) the libraries of the areas its areas may use, derived from the table above
# (runtime/CMakeLists.txt), and may use no other: the `layering.link_graph` test reads every
# archive's undefined symbols and fails on one defined in a library it may not use. A library
# must come after every library it uses. mocap_runtime is the appliance (every library but the
# benchmarks, the model tools and the three with an outside dependency: Vulkan, Cyclone DDS,
# OpenCV), which the programs and tests link.
set(runtime_libraries
    "mocap_core:core,skeleton,geometry,image,msg"
    "mocap_solver:fit,assoc"
    "mocap_calib:calib"
    "mocap_boardcal:boardcal"
    "mocap_detector:nn,crops"
    "mocap_pipeline:pipeline,fusion,sim"
    "mocap_gpu:gpu"
    "mocap_net:net"
    "mocap_outputs:out"
    "mocap_box:box"
    "mocap_bench:io,eval"
    "mocap_dds:dds"
    "mocap_model_tools:nn_import")
set(runtime_appliance_libraries mocap_core mocap_solver mocap_calib mocap_detector mocap_pipeline
    mocap_net mocap_outputs mocap_box)

# mocap_runtime_library_table(): for each library L of runtime_libraries, sets in the caller
# mocap_library_areas_<L> (its areas), mocap_library_uses_<L> (the libraries it may use) and
# mocap_library_below_<L> (those and the libraries below them), and mocap_library_names (all,
# lowest first); fails when a library uses one declared after it or an area is in no library
# or in two.
function(mocap_runtime_library_table)
  set(names "")
  foreach(entry IN LISTS runtime_libraries)
    string(REPLACE ":" ";" parts "${entry}")
    list(GET parts 0 lib)
    list(GET parts 1 areas)
    string(REPLACE "," ";" areas "${areas}")
    foreach(area IN LISTS areas)
      if(DEFINED lib_of_${area})
        message(FATAL_ERROR "cmake/RuntimeAreas.cmake: area '${area}' is in two libraries")
      endif()
      set(lib_of_${area} ${lib})
    endforeach()
    list(APPEND names ${lib})
    set(areas_${lib} "${areas}")
  endforeach()
  foreach(entry IN LISTS runtime_areas)
    string(REPLACE ":" ";" parts "${entry}")
    list(GET parts 0 area)
    if(NOT DEFINED lib_of_${area})
      message(FATAL_ERROR "cmake/RuntimeAreas.cmake: area '${area}' is in no library")
    endif()
    set(uses "")
    list(LENGTH parts np)
    if(np GREATER 1)
      list(GET parts 1 uses)
      string(REPLACE "," ";" uses "${uses}")
    endif()
    foreach(u IN LISTS uses)
      set(l ${lib_of_${u}})
      if(NOT l STREQUAL lib_of_${area})
        list(APPEND uses_${lib_of_${area}} ${l})
      endif()
    endforeach()
  endforeach()
  set(before "")
  foreach(lib IN LISTS names)
    if(uses_${lib})
      list(REMOVE_DUPLICATES uses_${lib})
    endif()
    foreach(u IN LISTS uses_${lib})
      if(NOT u IN_LIST before)
        message(FATAL_ERROR "cmake/RuntimeAreas.cmake: ${lib} uses ${u}, declared after it")
      endif()
    endforeach()
    list(APPEND before ${lib})
    set(below_${lib} "")
    foreach(u IN LISTS uses_${lib})
      list(APPEND below_${lib} ${u} ${below_${u}})
    endforeach()
    list(REMOVE_DUPLICATES below_${lib})
    set(mocap_library_areas_${lib} "${areas_${lib}}" PARENT_SCOPE)
    set(mocap_library_uses_${lib} "${uses_${lib}}" PARENT_SCOPE)
    set(mocap_library_below_${lib} "${below_${lib}}" PARENT_SCOPE)
  endforeach()
  set(mocap_library_names "${names}" PARENT_SCOPE)
endfunction()
