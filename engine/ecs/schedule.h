#pragma once
// The schedule: an ordered list of systems, each a free function with the component types it
// reads. A system whose read components all have no entity is skipped and never called, so a
// scene without subdivision surfaces never touches OpenSubdiv, one without area lights never
// builds a light table.

#include <chrono>
#include <string>
#include <typeindex>
#include <vector>

#include "ecs/registry.h"

namespace spangle::ecs {

/** Which of a system's reads must be non-empty for it to run. */
enum class RunWhen {
    AllPresent,  ///< every listed component has at least one entity
    AnyPresent   ///< at least one listed component has an entity
};

/** A system: name, reads, and the function. Context is whatever the caller passes along. */
template <class Context>
struct System {
    std::string name;                            ///< shown by --stats
    std::vector<std::type_index> reads;          ///< component types it reads
    std::vector<std::string> read_names;         ///< their names, for --stats
    RunWhen when = RunWhen::AllPresent;          ///< how reads gate the run
    void (*run)(Registry&, Context&) = nullptr;  ///< the system itself
};

/** What happened to one system in one run of the schedule. */
struct SystemReport {
    std::string name;      ///< system name
    bool ran = false;      ///< false: skipped because its inputs were empty
    std::string reason;    ///< why it was skipped ("no AreaLight"), empty when it ran
    double seconds = 0.0;  ///< wall time of the run
};

/** Helper to list component types: reads<Camera, Film>(). */
template <class... Cs>
std::vector<std::type_index> reads() {
    return {std::type_index(typeid(Cs))...};
}
template <class... Cs>
std::vector<std::string> read_names() {
    return {std::string(Cs::kName)...};
}

/** Ordered systems; run() executes them in order, skipping those without input. */
template <class Context>
class Schedule {
public:
    template <class... Reads>
    void add(std::string name, RunWhen when, void (*fn)(Registry&, Context&)) {
        systems_.push_back({std::move(name), reads<Reads...>(), read_names<Reads...>(), when, fn});
    }

    /** Whether system s would run on r now. */
    static bool should_run(const System<Context>& s, const Registry& r, std::string* reason) {
        bool any = false, all = true;
        std::string missing;
        for (std::size_t i = 0; i < s.reads.size(); ++i) {
            const bool present = r.count(s.reads[i]) > 0;
            any = any || present;
            all = all && present;
            if (!present) missing += (missing.empty() ? "" : ", ") + s.read_names[i];
        }
        const bool run = s.reads.empty() || (s.when == RunWhen::AllPresent ? all : any);
        if (!run && reason) *reason = "no " + missing;
        return run;
    }

    /** Runs every system whose inputs exist; returns one report per system, in order. */
    std::vector<SystemReport> run(Registry& r, Context& ctx) const {
        std::vector<SystemReport> out;
        for (const auto& s : systems_) {
            SystemReport rep{s.name, false, {}, 0.0};
            if (should_run(s, r, &rep.reason)) {
                const auto t0 = std::chrono::steady_clock::now();
                s.run(r, ctx);
                rep.seconds =
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
                rep.ran = true;
            }
            out.push_back(std::move(rep));
        }
        return out;
    }

    const std::vector<System<Context>>& systems() const { return systems_; }

private:
    std::vector<System<Context>> systems_;
};

}  // namespace spangle::ecs
