#pragma once
// What a session keeps between reloads, each entry keyed by everything that produced it (file
// identities, parameters). Systems look here before building and record what they built and
// reused; each key is owned by the system that used it, so that a system a reload skips keeps
// its entries. Entries no load used are evicted after each successful load, so memory follows the
// scene, not the number of reloads.

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "geometry/cage.h"
#include "geometry/triangle_mesh.h"
#include "render/lights.h"
#include "shading/material.h"

namespace spangle {

/** The session's cache of built meshes, cages, materials and environment maps. */
struct BuildCache {
    std::map<std::string, std::shared_ptr<const TriangleMesh>> meshes;
    std::map<std::string, std::shared_ptr<const Cage>> cages;
    std::map<std::string, std::shared_ptr<MaterialInstance>> materials;
    std::map<std::string, std::shared_ptr<const EnvironmentMap>> environments;
    std::string owner;                             ///< the system now running
    std::map<std::string, std::string> used;       ///< key -> owner, of the load in progress
    std::map<std::string, std::string> last_used;  ///< key -> owner, of the live scene's load
    std::vector<std::string> built;                ///< what the load in progress built
    std::map<std::string, int> reused;             ///< kind -> count reused by the load in progress

    /** Looks `key` up in `map`; on a hit counts it as reused under `kind`. */
    template <class T>
    std::shared_ptr<T> find(std::map<std::string, std::shared_ptr<T>>& map, const std::string& key,
                            const char* kind) {
        used[key] = owner;
        auto it = map.find(key);
        if (it == map.end()) return nullptr;
        ++reused[kind];
        return it->second;
    }
    void begin() {
        used.clear();
        built.clear();
        reused.clear();
    }
    /** A skipped system keeps what it built last time: its keys stay in use. */
    void keep(const std::string& system) {
        for (const auto& [key, by] : last_used)
            if (by == system) used[key] = by;
    }
    /** Drops every entry the load just committed does not use. */
    void evict() {
        last_used = used;
        auto prune = [&](auto& map) {
            for (auto it = map.begin(); it != map.end();)
                it = used.count(it->first) ? std::next(it) : map.erase(it);
        };
        prune(meshes);
        prune(cages);
        prune(materials);
        prune(environments);
    }
};

/** The entry of `map` for key(), or make()'s result, stored there and recorded as `what` built
 *  (when not empty). Without a cache it only calls make(), and key() is never computed. Reuses
 *  are counted under `kind`. */
template <class T, class Key, class Make>
std::shared_ptr<T> build_cached(BuildCache* cache,
                                std::map<std::string, std::shared_ptr<T>> BuildCache::*map,
                                const char* kind, Key&& key, Make&& make, const std::string& what) {
    if (!cache) return std::shared_ptr<T>(make());
    const std::string k = key();
    if (auto hit = cache->find(cache->*map, k, kind)) return hit;
    std::shared_ptr<T> built(make());
    (cache->*map)[k] = built;
    if (!what.empty()) cache->built.push_back(what);
    return built;
}

}  // namespace spangle
