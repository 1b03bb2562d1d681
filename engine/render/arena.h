#pragma once
// A bump allocator handed to plugins as SpangleArena_v3: blocks are kept between batches and
// reset, so steady-state shading allocates nothing.

#include <cstddef>
#include <memory>
#include <vector>

#include "spangle/plugin.h"

namespace spangle {

/** Bump allocator over a list of blocks; reset() keeps the blocks. */
class ScratchArena {
public:
    /** `bytes` aligned to `align` (power of two <= 64), or nullptr for an invalid request. */
    void* allocate(std::size_t bytes, std::size_t align);
    /** Makes all memory reusable; pointers handed out before become invalid. */
    void reset() {
        block_ = 0;
        offset_ = 0;
    }
    /** The C view for plugins; valid while this arena lives. */
    SpangleArena_v3 api() { return {this, &ScratchArena::allocate_c}; }

private:
    static void* allocate_c(void* self, std::size_t bytes, std::size_t align) {
        try {  // blocks_ may fail to grow: NULL for the plugin, never an exception
            return static_cast<ScratchArena*>(self)->allocate(bytes, align);
        } catch (...) {
            return nullptr;
        }
    }
    static constexpr std::size_t kBlockSize = 1 << 20;
    struct Block {
        std::unique_ptr<std::byte[]> data;
        std::size_t size;
    };
    std::vector<Block> blocks_;
    std::size_t block_ = 0;   ///< current block
    std::size_t offset_ = 0;  ///< bytes used in the current block
};

}  // namespace spangle
