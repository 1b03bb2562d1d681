// Cost of a material per shading point, through the real plugin ABI: prepare + one eval + one
// sample per point, in batches of 256 points as the integrator makes them. Run:
//     ./build/spangle_bench                      (all)
//     ./build/spangle_bench --benchmark_filter=Flake
// Figures are reported per shading point (items_per_second is points per second).

#include <benchmark/benchmark.h>
#include <fmt/format.h>

#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <vector>

#include "core/hash.h"
#include "render/arena.h"
#include "shading/material.h"
#include "shading/plugin_loader.h"
#include "test_support.h"

namespace spangle {
namespace {

constexpr uint32_t kBatch = 256;

/** A material instance and a batch of shading points with a given footprint size. */
struct Fixture {
    ColorConfig color = test::shipped_config();
    std::unique_ptr<HostServices> host;
    PluginLoader loader{plugin_search_path({})};
    std::unique_ptr<MaterialInstance> mat;
    std::vector<float> px, py, pz, wox, woy, woz, u, v, dudx, dudy, dvdx, dvdy, area;
    std::vector<float> zero, one;
    std::vector<uint32_t> flags, ids;
    std::vector<float> wix, wiy, wiz, f_r, f_g, f_b, pdf, u0, u1, u2;
    std::vector<uint32_t> sflags;
    std::vector<std::byte> closures;
    ScratchArena arena;

    Fixture(const std::string& plugin, const std::string& model, const ParamList& params,
            double footprint, bool differentials, bool coherent = false) {
        host = std::make_unique<HostServices>(color, test::quiet_log());
        Material m;
        m.name = "bench";
        m.plugin = plugin;
        m.model = model;
        m.params = params;
        mat = create_material(loader, m, *host);
        for (auto* a : {&px,   &py,  &pz,  &wox, &woy, &woz, &u,   &v,   &dudx, &dudy, &dvdx, &dvdy,
                        &area, &wix, &wiy, &wiz, &f_r, &f_g, &f_b, &pdf, &u0,   &u1,   &u2})
            a->resize(kBatch);
        zero.assign(kBatch, 0.0f);
        one.assign(kBatch, 1.0f);
        flags.resize(kBatch);
        ids.resize(kBatch);
        sflags.resize(kBatch);
        for (uint32_t i = 0; i < kBatch; ++i) {
            const float c = 0.3f + 0.65f * sample_1d(1, i, 0, 0),
                        phi = 6.28318f * sample_1d(1, i, 0, 1);
            const float s = std::sqrt(1.0f - c * c);
            wox[i] = s * std::cos(phi);
            woy[i] = s * std::sin(phi);
            woz[i] = c;
            // Incident directions near the mirror direction, where glossy lobes have their mass.
            const float ci = 0.3f + 0.65f * sample_1d(2, i, 0, 0),
                        pi = phi + 3.14159f + 0.3f * (sample_1d(2, i, 0, 1) - 0.5f);
            const float si = std::sqrt(1.0f - ci * ci);
            wix[i] = si * std::cos(pi);
            wiy[i] = si * std::sin(pi);
            wiz[i] = ci;
            // Scattered over a million uv tiles (worst case), or coherent: a 16 x 16 block of
            // neighbouring pixels as the integrator's tiles produce them.
            const float spread = coherent ? 16.0f * static_cast<float>(footprint) : 1000.0f;
            u[i] = 0.37f + spread * sample_1d(3, i, 0, 0);
            v[i] = 0.61f + spread * sample_1d(3, i, 0, 1);
            dudx[i] = dvdy[i] = static_cast<float>(footprint);
            dudy[i] = dvdx[i] = 0.0f;
            area[i] = 1.0f;
            flags[i] = differentials ? SPANGLE_SHADING_HAS_DIFFERENTIALS : 0u;
            ids[i] = i;
            u0[i] = sample_1d(4, i, 0, 0);
            u1[i] = sample_1d(4, i, 0, 1);
            u2[i] = sample_1d(4, i, 0, 2);
        }
        closures.resize(kBatch * mat->model().closure_size + 16);
    }

    void shade() {
        // Object space mirrors uv (the plane z = 0 of the object): the uv path does not read it.
        const SpangleShadingBatch_v3 b{
            kBatch,      px.data(),   py.data(),    pz.data(),   wox.data(),  woy.data(),
            woz.data(),  u.data(),    v.data(),     dudx.data(), dudy.data(), dvdx.data(),
            dvdy.data(), area.data(), u.data(),     v.data(),    zero.data(), zero.data(),
            zero.data(), one.data(),  dudx.data(),  dvdx.data(), zero.data(), dudy.data(),
            dvdy.data(), zero.data(), flags.data(), ids.data(),  nullptr,     nullptr};
        void* cl = closures.data();
        std::size_t space = closures.size();
        cl = std::align(16, kBatch * mat->model().closure_size, cl, space);
        arena.reset();
        SpangleArena_v3 a = arena.api();
        mat->model().prepare(mat->instance(), &b, cl, &a);
        SpangleEvalBatch_v3 e{kBatch,     nullptr,    wix.data(), wiy.data(),
                              wiz.data(), f_r.data(), f_g.data(), f_b.data(),
                              pdf.data(), nullptr,    nullptr,    nullptr};
        mat->model().eval(mat->instance(), cl, &e);
        std::vector<float>& sx = wix;  // sample() overwrites the query directions: same cost
        SpangleSampleBatch_v3 s{kBatch,     nullptr,    u0.data(),     u1.data(),  u2.data(),
                                sx.data(),  wiy.data(), wiz.data(),    f_r.data(), f_g.data(),
                                f_b.data(), pdf.data(), sflags.data(), nullptr,    nullptr,
                                nullptr,    nullptr};
        mat->model().sample(mat->instance(), cl, &s);
        benchmark::DoNotOptimize(f_r.data());
    }
};

ParamEntry number(const std::string& name, double x) {
    ParamEntry p;
    p.name = name;
    p.kind = ParamEntry::Kind::Number;
    p.number[0] = x;
    return p;
}
ParamEntry text(const std::string& name, const std::string& s) {
    ParamEntry p;
    p.name = name;
    p.kind = ParamEntry::Kind::String;
    p.text = s;
    return p;
}

void run(benchmark::State& state, Fixture& f) {
    // Warm up outside the timing: tables a material builds on first use (the flake smooth lobe's
    // view slices) are a one-off cost per process, not a per-point one.
    for (int i = 0; i < 20; ++i) f.shade();
    for (auto _ : state) f.shade();
    state.SetItemsProcessed(static_cast<int64_t>(state.iterations()) * kBatch);
    state.counters["us_per_point"] =
        benchmark::Counter(static_cast<double>(state.iterations()) * kBatch * 1e-6,
                           benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

void BM_SmoothGgxConductor(benchmark::State& state) {
    Fixture f("smooth", "conductor", {number("roughness", 0.15), text("preset", "aluminium")}, 0.0,
              false);
    run(state, f);
}
BENCHMARK(BM_SmoothGgxConductor);

/** Flakes with density 1e5 per uv square: a square footprint of side sqrt(lambda / 1e5). Args:
 *  lambda (0: the smooth regime, no differentials), algorithm (0 tree, 1 enumerate), coherent
 *  footprints (1: a 16 x 16 block of neighbouring pixels, as the integrator's tiles make them),
 *  colour table (1: on). The discrete lobe is forced (min_flakes 5e8) except in the smooth
 *  regime. */
void BM_Flake(benchmark::State& state) {
    const double lambda = static_cast<double>(state.range(0));
    const bool smooth_regime = state.range(0) == 0;
    const bool enumerate = state.range(1) != 0;
    const bool coherent = state.range(2) != 0;
    ParamList p = {number("density", 1e5),
                   number("flake_roughness", 0.15),
                   number("flake_weight", 1.0),
                   number("base_color", 0.0),
                   number("min_flakes", 5e8),
                   number("max_flakes", 1e9),
                   text("algorithm", enumerate ? "enumerate" : "tree")};
    if (state.range(3) != 0) {
        ParamEntry table = number("color_table", 1.0);
        table.kind = ParamEntry::Kind::Bool;
        p.push_back(table);
    }
    Fixture f("flake", "flake", p, smooth_regime ? 0.0 : std::sqrt(lambda / 1e5), !smooth_regime,
              coherent);
    state.SetLabel(smooth_regime
                       ? "smooth regime (no differentials)"
                       : fmt::format("lambda {}, {}{}{}", state.range(0),
                                     enumerate ? "enumerate" : "tree", coherent ? ", coherent" : "",
                                     state.range(3) ? ", colour table" : ""));
    run(state, f);
}
BENCHMARK(BM_Flake)->Args({0, 0, 0, 0});
BENCHMARK(BM_Flake)
    ->Args({10, 0, 0, 0})
    ->Args({100, 0, 0, 0})
    ->Args({1000, 0, 0, 0})
    ->Args({10000, 0, 0, 0})
    ->Args({100000, 0, 0, 0});
BENCHMARK(BM_Flake)
    ->Args({10, 1, 0, 0})
    ->Args({100, 1, 0, 0})
    ->Args({1000, 1, 0, 0})
    ->Args({10000, 1, 0, 0})
    ->Args({100000, 1, 0, 0});
/** Neighbouring shading points, as a render makes them, and the colour table's cost. */
BENCHMARK(BM_Flake)->Args({100, 0, 1, 0})->Args({10000, 0, 1, 0})->Args({100, 0, 0, 1});

/** The fixed cost of a flake material: creating an instance, whose smooth lobe (and rough coat)
 *  tables are built (cold: the table cache off) or read from the persistent cache (cached).
 *  Args: material (index into kTableMaterials), cached. One build thread unless
 *  SPANGLE_FLAKE_THREADS says otherwise (set it before running to compare). */
struct TableMaterial {
    const char* label;
    double alpha, gamma;
    bool rough_coat;
};
constexpr TableMaterial kTableMaterials[] = {
    {"default: alpha 0.15, gamma 3", 0.15, 3.0, false},
    {"car paint of the issue: alpha 0.047, gamma 5", 0.047, 5.0, false},
    {"alpha 0.15, gamma 10", 0.15, 10.0, false},
    {"alpha 0.05, gamma 10", 0.05, 10.0, false},
    {"alpha 0.35, gamma 30", 0.35, 30.0, false},
    {"alpha 0.001, gamma 45 (cone 400x the lobe)", 0.001, 45.0, false},
    {"default with a rough coat (0.3)", 0.15, 3.0, true},
};

void BM_FlakeTables(benchmark::State& state) {
    const TableMaterial& tm = kTableMaterials[state.range(0)];
    const bool cached = state.range(1) != 0;
    const std::string dir = fmt::format("/tmp/spangle_bench_tables_{}", ::getpid());
    setenv("SPANGLE_FLAKE_CACHE", cached ? dir.c_str() : "off", 1);
    if (!std::getenv("SPANGLE_FLAKE_THREADS")) setenv("SPANGLE_FLAKE_THREADS", "1", 1);
    ColorConfig color = test::shipped_config();
    HostServices host(color, test::quiet_log());
    PluginLoader loader{plugin_search_path({})};
    Material m;
    m.name = "bench";
    m.plugin = "flake";
    m.model = "flake";
    m.params = {number("flake_roughness", tm.alpha), number("gamma", tm.gamma)};
    if (tm.rough_coat) {
        ParamEntry coat = number("coat", 1.0);
        coat.kind = ParamEntry::Kind::Bool;
        m.params.push_back(coat);
        m.params.push_back(number("coat_roughness", 0.3));
    }
    if (cached) create_material(loader, m, host);  // fills the cache
    for (auto _ : state) benchmark::DoNotOptimize(create_material(loader, m, host));
    state.SetLabel(fmt::format("{}, {}", tm.label, cached ? "cached" : "cold"));
    state.counters["ms_per_material"] =
        benchmark::Counter(static_cast<double>(state.iterations()) * 1e-3,
                           benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
}
BENCHMARK(BM_FlakeTables)
    ->ArgsProduct({{0, 1, 2, 3, 4, 5, 6}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(0.5);

/** `spangle_bench --shade CONFIG BATCHES` shades BATCHES batches of one configuration once, with
 *  no timing: for instruction counts under valgrind --tool=callgrind, which the machine's load
 *  does not change (run two batch counts and take the difference to drop the set-up). CONFIG is
 *  `conductor` or `flake:LAMBDA:ALGORITHM` (tree or enumerate; lambda 0: the smooth regime). */
int shade_only(const std::string& config, int batches) {
    std::unique_ptr<Fixture> f;
    if (config == "conductor") {
        f = std::make_unique<Fixture>(
            "smooth", "conductor",
            ParamList{number("roughness", 0.15), text("preset", "aluminium")}, 0.0, false);
    } else if (config.rfind("flake:", 0) == 0) {
        const auto colon = config.find(':', 6);
        const double lambda = std::stod(config.substr(6, colon - 6));
        const std::string algorithm =
            colon == std::string::npos ? "tree" : config.substr(colon + 1);
        const ParamList p = {number("density", 1e5),      number("flake_roughness", 0.15),
                             number("flake_weight", 1.0), number("base_color", 0.0),
                             number("min_flakes", 5e8),   number("max_flakes", 1e9),
                             text("algorithm", algorithm)};
        f = std::make_unique<Fixture>("flake", "flake", p,
                                      lambda > 0 ? std::sqrt(lambda / 1e5) : 0.0, lambda > 0);
    } else {
        fmt::print(stderr, "unknown configuration '{}'\n", config);
        return 2;
    }
    for (int i = 0; i < batches; ++i) f->shade();
    return 0;
}

}  // namespace
}  // namespace spangle

int main(int argc, char** argv) {
    if (argc == 4 && std::string(argv[1]) == "--shade")
        return spangle::shade_only(argv[2], std::atoi(argv[3]));
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}
