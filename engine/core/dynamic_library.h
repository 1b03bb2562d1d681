#pragma once
// Binding functions of a library opened with dlopen (the OpenImageIO module, Open Image Denoise).

#include <dlfcn.h>

namespace spangle {

/** dlsym into a typed function pointer; false when the symbol is missing. */
template <class Fn>
bool bind_symbol(void* handle, const char* name, Fn& fn) {
    fn = reinterpret_cast<Fn>(dlsym(handle, name));
    return fn != nullptr;
}

}  // namespace spangle
