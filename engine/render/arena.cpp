#include "render/arena.h"

#include <cstdint>
#include <new>

namespace spangle {

void* ScratchArena::allocate(std::size_t bytes, std::size_t align) {
    if (align == 0 || align > 64 || (align & (align - 1)) != 0 || bytes > (std::size_t{1} << 40))
        return nullptr;
    // Worst case we need bytes + align - 1 in one block.
    const std::size_t need = bytes + align - 1;
    while (true) {
        if (block_ < blocks_.size()) {
            Block& b = blocks_[block_];
            auto base = reinterpret_cast<std::uintptr_t>(b.data.get()) + offset_;
            const std::uintptr_t aligned =
                (base + align - 1) & ~(static_cast<std::uintptr_t>(align) - 1);
            const std::size_t used = offset_ + (aligned - base) + bytes;
            if (used <= b.size) {
                offset_ = used;
                return reinterpret_cast<void*>(aligned);
            }
            ++block_;
            offset_ = 0;
            continue;
        }
        const std::size_t size = need > kBlockSize ? need : kBlockSize;
        // Not zeroed (a plugin writes what it asks for), and no memory is NULL as the ABI says:
        // an exception must not unwind through the plugin's C frames.
        std::unique_ptr<std::byte[]> data(new (std::nothrow) std::byte[size]);
        if (!data) return nullptr;
        blocks_.push_back({std::move(data), size});
        block_ = blocks_.size() - 1;
        offset_ = 0;
    }
}

}  // namespace spangle
