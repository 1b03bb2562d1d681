# Debian 12 packages and their CMake traps (../shared/NOTES-deps.md). Every dependency is
# imported as a target here, once, so that the rest of the build only links names.
find_package(PkgConfig REQUIRED)
find_package(Threads REQUIRED)

find_package(embree 3 REQUIRED)

find_package(fmt REQUIRED)
find_package(TBB REQUIRED)
find_package(tomlplusplus REQUIRED)
find_package(CLI11 REQUIRED)
find_package(TinyGLTF REQUIRED)  # glTF scenes: Debian ships it as a shared library (TinyGLTF::TinyGLTF)
# Compressed glTF geometry: KHR_draco_mesh_compression (draco::draco) and EXT_meshopt_compression
# (meshoptimizer). Trap: Debian's libdraco.so exports a tinygltf of its own (its glTF transcoder's,
# another version). Whichever library comes first in a link (and so in the program's needed
# libraries) provides tinygltf's symbols, so libdraco must come after libtinygltf:
# engine/CMakeLists.txt lists TinyGLTF::TinyGLTF first, and no target links draco ahead of
# spangle_core (spangle_tests did, and its glTF reads crashed in draco's tinygltf: FsCallbacks of
# another layout). The test GltfCompression.TinygltfIsDebiansNotDracos checks it. The static
# archive is no way out: libtinygltf.so's stb_image references pull the archive member that
# holds draco's tinygltf.
find_package(draco CONFIG REQUIRED)
find_package(meshoptimizer CONFIG REQUIRED)

# OpenImageIO's imported target names /usr/include/opencv4, which Debian does not ship;
# CMake refuses to generate with a missing include directory, so drop that entry.
find_package(OpenImageIO REQUIRED)
get_target_property(_oiio_inc OpenImageIO::OpenImageIO INTERFACE_INCLUDE_DIRECTORIES)
if(_oiio_inc)
    list(FILTER _oiio_inc EXCLUDE REGEX "opencv4")
    set_target_properties(OpenImageIO::OpenImageIO PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_oiio_inc}")
endif()

# EXR files are read and written with OpenEXR itself, PNG previews with libpng: OpenImageIO is
# linked only by the module that reads other formats (engine/oiio/).
find_package(OpenEXR CONFIG REQUIRED)
find_package(PNG REQUIRED)
# gzip'd pbrt scenes (.pbrt.gz) are inflated with zlib.
find_package(ZLIB REQUIRED)

# OpenColorIO's CMake config computes a wrong prefix on Debian: use pkg-config.
pkg_check_modules(OCIO REQUIRED IMPORTED_TARGET OpenColorIO)

# OpenSubdiv's config references static libraries Debian does not ship: find it by hand.
find_library(OSD_CPU_LIBRARY osdCPU REQUIRED)
find_path(OSD_INCLUDE_DIR opensubdiv/far/topologyRefiner.h REQUIRED)
add_library(spangle_opensubdiv INTERFACE)
target_link_libraries(spangle_opensubdiv INTERFACE ${OSD_CPU_LIBRARY})
target_include_directories(spangle_opensubdiv SYSTEM INTERFACE ${OSD_INCLUDE_DIR})

# MPI (optional): the C API and a launcher (mpiexec) for the tests.
set(SPANGLE_HAVE_MPI OFF)
if(SPANGLE_MPI)
    find_package(MPI COMPONENTS C)
    if(MPI_C_FOUND)
        set(SPANGLE_HAVE_MPI ON)
        message(STATUS "MPI: spangle renders over MPI ranks (${MPI_C_LIBRARIES}; ${MPIEXEC_EXECUTABLE})")
    else()
        message(STATUS "MPI: not found (install libopenmpi-dev): spangle renders in one process")
    endif()
endif()

if(SPANGLE_BUILD_TESTS)
    find_package(GTest REQUIRED)
    find_package(benchmark QUIET)
endif()
