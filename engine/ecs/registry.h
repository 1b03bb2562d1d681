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

    /** Whether this registry's pool of `type` and other's hold the same entities with the same
     *  values (an absent pool and an empty one are the same). */
    bool same_pool(std::type_index type, const Registry& other) const {
        const PoolBase* a = find_base(type);
        const PoolBase* b = other.find_base(type);
        const std::size_t na = a ? a->size() : 0, nb = b ? b->size() : 0;
        if (na == 0 && nb == 0) return true;
        return a && b && a->same_as(*b);
    }

    /** Copies e's component of `type` from `from` into this registry (e must be alive here);
     *  false when `from` has none for e. Hot reload hands a skipped system's components over
     *  with it. */
    bool copy_component(std::type_index type, const Registry& from, Entity e) {
        const PoolBase* source = from.find_base(type);
        if (!source) return false;
        SPANGLE_CHECK(alive(e), "copy_component() onto a dead entity");
        auto it = pools_.find(type);
        if (it == pools_.end()) it = pools_.emplace(type, source->empty_like()).first;
        return it->second->copy_from(*source, e);
    }

    /** The entities that have the component `type` (empty when there is no pool). */
    std::vector<Entity> entities_of(std::type_index type) const {
        std::vector<Entity> out;
        if (const PoolBase* p = find_base(type)) out = p->entity_list();
        return out;
    }

    /** Names of the component types whose pools differ between a and b (an absent pool and an
     *  empty one are the same), skipping the types in `ignore`. */
    static std::vector<std::string> changed_types(const Registry& a, const Registry& b,
                                                  const std::vector<std::type_index>& ignore) {
        std::vector<std::string> out;
        for (const auto& [type, name] : changed_pools(a, b, ignore)) out.push_back(name);
        return out;
    }

    /** The component types (with their names) whose pools differ between a and b, sorted by
     *  name, skipping the types in `ignore`. */
    static std::vector<std::pair<std::type_index, std::string>> changed_pools(
        const Registry& a, const Registry& b, const std::vector<std::type_index>& ignore) {
        std::vector<std::pair<std::type_index, std::string>> out;
        auto check = [&](std::type_index t, const PoolBase& p) {
            if (std::find(ignore.begin(), ignore.end(), t) != ignore.end()) return;
            if (!a.same_pool(t, b)) out.emplace_back(t, p.name());
        };
        for (const auto& [t, pa] : a.pools_) check(t, *pa);
        for (const auto& [t, pb] : b.pools_)
            if (a.pools_.find(t) == a.pools_.end()) check(t, *pb);
        std::sort(out.begin(), out.end(),
                  [](const auto& x, const auto& y) { return x.second < y.second; });
        return out;
    }

private:
    const PoolBase* find_base(std::type_index type) const {
        auto it = pools_.find(type);
        return it == pools_.end() ? nullptr : it->second.get();
    }

    EntityAllocator entities_;
    std::unordered_map<std::type_index, std::unique_ptr<PoolBase>> pools_;
};

}  // namespace spangle::ecs
