# Compiler warnings for every Spangle target. -Wconversion catches the float/int slips that
# FLAKES.md section 8 lists (abs() on a float picking the integer overload).
add_library(spangle_warnings INTERFACE)
target_compile_options(spangle_warnings INTERFACE
    -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wno-sign-conversion
    -Wnon-virtual-dtor -Wold-style-cast -Wcast-align -Wdouble-promotion
    $<$<CXX_COMPILER_ID:Clang>:-Wno-double-promotion> $<$<BOOL:${SPANGLE_WERROR}>:-Werror>)
