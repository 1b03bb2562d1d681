#pragma once
// The registry: a container of entities and one pool per component type. It owns no behaviour;
// systems are free functions that read and write its pools.

#include <algorithm>
#include <memory>
#include <string>
#include <typeindex>
#include <unordered_map>
#include <vector>

#include "ecs/entity.h"
#include "ecs/pool.h"

namespace spangle::ecs {

/** Entities and their component pools. Not thread-safe for structural changes. */
class Registry {
public:
    Entity create() { return entities_.create(); }
    /** Destroys e and removes all its components; false when e is not alive. */
    bool destroy(Entity e) {
        if (!entities_.alive(e)) return false;
        for (auto& [type, pool] : pools_) pool->remove(e);
        return entities_.destroy(e);
    }
    bool alive(Entity e) const { return entities_.alive(e); }
    uint32_t live_count() const { return entities_.live_count(); }

    /** Adds or replaces e's component C. */
    template <class C>
    void put(Entity e, const C& value) {
        SPANGLE_CHECK(alive(e), "put() on a dead entity");
        pool<C>().put(e, value);
    }
    template <class C>
    bool has(Entity e) const {
        const Pool<C>* p = find_pool<C>();
        return p && p->has(e);
    }
    template <class C>
    C get(Entity e) const {
        const Pool<C>* p = find_pool<C>();
        SPANGLE_CHECK(p != nullptr, "no pool for this component");
        return p->get(e);
    }
    template <class C>
    bool remove(Entity e) {
        Pool<C>* p = find_pool<C>();
        return p && p->remove(e);
    }

    /** The pool of C, created empty on first use. */
    template <class C>
    Pool<C>& pool() {
        auto it = pools_.find(std::type_index(typeid(C)));
        if (it == pools_.end())
            it = pools_.emplace(std::type_index(typeid(C)), std::make_unique<Pool<C>>()).first;
        return static_cast<Pool<C>&>(*it->second);
    }
    /** The pool of C, or nullptr when no C was ever added. */
    template <class C>
    const Pool<C>* find_pool() const {
        auto it = pools_.find(std::type_index(typeid(C)));
        return it == pools_.end() ? nullptr : static_cast<const Pool<C>*>(it->second.get());
    }
    template <class C>
    Pool<C>* find_pool() {
        auto it = pools_.find(std::type_index(typeid(C)));
        return it == pools_.end() ? nullptr : static_cast<Pool<C>*>(it->second.get());
    }
    /** Number of entities with component C (0 when there is no pool). */
    template <class C>
    std::size_t count() const {
        const Pool<C>* p = find_pool<C>();
        return p ? p->size() : 0;
    }
    /** Size of the pool for a type id, for the schedule. */
    std::size_t count(std::type_index type) const {
        auto it = pools_.find(type);
        return it == pools_.end() ? 0 : it->second->size();
    }

    /** Names of the component types whose pools differ between a and b (an absent pool and an
     *  empty one are the same), skipping the types in `ignore`. */
    static std::vector<std::string> changed_types(const Registry& a, const Registry& b,
                                                  const std::vector<std::type_index>& ignore) {
        std::vector<std::string> out;
        auto differs = [&](std::type_index t, const PoolBase* pa, const PoolBase* pb) {
            for (const auto& i : ignore)
                if (i == t) return false;
            const std::size_t na = pa ? pa->size() : 0, nb = pb ? pb->size() : 0;
            if (na == 0 && nb == 0) return false;
            return !pa || !pb || !pa->same_as(*pb);
        };
        for (const auto& [t, pa] : a.pools_) {
            auto it = b.pools_.find(t);
            const PoolBase* pb = it == b.pools_.end() ? nullptr : it->second.get();
            if (differs(t, pa.get(), pb)) out.push_back(pa->name());
        }
        for (const auto& [t, pb] : b.pools_)
            if (a.pools_.find(t) == a.pools_.end() && differs(t, nullptr, pb.get()))
                out.push_back(pb->name());
        std::sort(out.begin(), out.end());
        return out;
    }

private:
    EntityAllocator entities_;
    std::unordered_map<std::type_index, std::unique_ptr<PoolBase>> pools_;
};

}  // namespace spangle::ecs
