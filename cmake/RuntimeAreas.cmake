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
    "io:core,msg,skeleton"
    # the solver: skeleton fitting, the 4D association, calibration from people and boards
    "fit:core,geometry,skeleton"
    "assoc:core,fit,geometry,msg,skeleton"
    "calib:core,fit,geometry,image,io,msg,skeleton"
    "boardcal:core,geometry,image,msg"
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
    "out:core,io,msg,skeleton"
    # benchmarks and evaluation (Shelf, the metrics), linked by `mocap` and the tests
    "eval:assoc,core,fit,geometry,io,msg,pipeline,skeleton"
    "dds:core,fusion,msg,pipeline,skeleton"
    # the appliance: calibration lifecycle, status, outputs, takes
    "box:assoc,calib,core,geometry,image,msg,net,nn,out,pipeline")
