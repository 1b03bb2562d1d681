// The flake plugin's tables: the fast exact integral they are built from (against the reference
// cap integral), the exact mass they are normalised to, and the persistent cache: a cached table
// is the built one bit for bit; damaged, foreign and stale files are rebuilt, never read;
// processes writing the same table at once leave a complete one; the size bound holds.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "cap_integral.h"
#include "coat.h"
#include "core/hash.h"
#include "discrete_lobe.h"
#include "flake_support.h"
#include "slope_integral.h"
#include "smooth_lobe.h"
#include "table_cache.h"
#include "test_support.h"

namespace spangle::test::flake_tables {
namespace {

namespace fl = spangle::flake;
namespace fs = std::filesystem;

/** A dielectric Fresnel table (steep at grazing), so that the Fresnel weighting is exercised. */
fl::FresnelTable dielectric() {
    fl::FresnelTable t;
    for (int i = 0; i < fl::FresnelTable::kNodes; ++i) {
        const float c = static_cast<float>(i) / (fl::FresnelTable::kNodes - 1);
        for (int k = 0; k < 3; ++k)
            t.rgb[i][k] = mf::fresnel_dielectric(c, 1.5f + 0.3f * static_cast<float>(k));
    }
    return t;
}

double uniform(uint64_t seed, uint64_t k) {
    return to_unit_double(hash2(seed, k));
}

TEST(FlakeTables, SlopeIntegralMatchesTheFlakesGenerativeProcess) {
    // The definition by brute force: a stratified grid of 2000^2 visible normals, their mirror
    // directions, the share within gamma of wi and above the horizon, Fresnel-weighted. Peak,
    // off-peak and grazing views, directions under the cone's reach of the horizon, cones from
    // 100 times narrower than the flake lobe (alpha 0.5, gamma 0.5) to 400 times wider (alpha
    // 0.001, gamma 45), and the very rough wide case where cap_integral errs by 4%.
    const fl::FresnelTable fresnel = dielectric();
    struct Case {
        float alpha, gamma_deg, cos_o, cos_i, phi_i;
    };
    const Case cases[] = {{0.15f, 3, 0.7f, 0.7f, 3.14159f},   {0.15f, 10, 0.7f, 0.5f, 3.0f},
                          {0.3f, 30, 0.5f, 0.6f, 2.5f},       {0.001f, 10, 0.7f, 0.7f, 3.1f},
                          {0.15f, 3, 0.05f, 0.05f, 3.14159f}, {0.15f, 30, 0.05f, 0.2f, 3.0f},
                          {1.0f, 45, 0.3f, 0.1f, 1.0f},       {0.15f, 1, 0.2f, 0.25f, 3.1f},
                          {1.0f, 45, 0.037f, 0.089f, 3.34f},  {0.5f, 0.5f, 0.5f, 0.8f, 1.73f},
                          {0.001f, 45, 0.79f, 0.2f, 3.6f},    {0.15f, 3, 0.01f, 0.02f, 3.1f}};
    for (const Case& c : cases) {
        const double sin2 = std::pow(std::sin(0.5 * c.gamma_deg * M_PI / 180.0), 2.0);
        const fl::V3 wo = fdir(c.cos_o, 0.0f), wi = fdir(c.cos_i, c.phi_i);
        float i_f[3], i_1;
        fl::slope_integral(c.alpha, sin2, &fresnel, wo, wi, i_f, i_1);
        constexpr int kGrid = 2000;
        double hits = 0, hits_f = 0;
        const auto thr = static_cast<float>(4.0 * sin2);
        for (int a = 0; a < kGrid; ++a)
            for (int b = 0; b < kGrid; ++b) {
                const fl::V3 m = mf::ggx_sample_visible(wo, c.alpha, c.alpha,
                                                        static_cast<float>((a + 0.5) / kGrid),
                                                        static_cast<float>((b + 0.5) / kGrid));
                const fl::V3 r = mf::reflect(wo, m), d = r - wi;
                if (r.z <= 0.0f || mf::dot(d, d) > thr) continue;
                float f[3];
                fresnel.eval(mf::dot(wo, m), f);
                hits += 1.0;
                hits_f += f[1];
            }
        const double n = static_cast<double>(kGrid) * kGrid, p = hits / n;
        // A stratified grid errs less than random sampling; its binomial error bounds it. Plus
        // 1e-3 for the grid's cells cut by the cone's rim (about sqrt(n) of them at the scale of
        // the smallest regions here).
        const double se = std::sqrt(p * (1.0 - p) / n);
        SCOPED_TRACE(testing::Message() << "alpha " << c.alpha << " gamma " << c.gamma_deg
                                        << " cos_o " << c.cos_o << " cos_i " << c.cos_i);
        ASSERT_GT(hits, 100.0) << "the case must light wi";
        EXPECT_NEAR(i_1, p, 4.0 * se + 1e-3 * p);
        EXPECT_NEAR(i_f[1], hits_f / n, 4.0 * se + 2e-3 * hits_f / n);
    }
}

TEST(FlakeTables, SlopeIntegralAgreesWithTheCapIntegral) {
    // The two exact methods, in different coordinates (the stretched hemisphere about the
    // region's centre; the slope plane about the normal, or by the boundary) and quadratures,
    // over the lobe, for the cones the tables are built for (tan(gamma/2) / alpha up to 2) and
    // views down to cos 0.05. Where they differ, the slope integral is the one that matches a
    // brute force (see the test above); cap_integral's error there is up to 1e-3 for cones much
    // narrower than the lobe (tiny regions), 4e-2 at grazing with cones wider than the lobe.
    const fl::FresnelTable fresnel = dielectric();
    struct Case {
        float alpha, gamma_deg;
    };
    double worst = 0.0, worst_f = 0.0;
    for (const Case& c : {Case{0.15f, 3}, Case{0.15f, 10}, Case{0.05f, 10}, Case{0.35f, 30},
                          Case{0.01f, 1}, Case{0.3f, 5}}) {
        const double sin2 = std::pow(std::sin(0.5 * c.gamma_deg * M_PI / 180.0), 2.0);
        const float kappa = std::tan(0.5f * c.gamma_deg * kPi / 180.0f) / c.alpha;
        for (uint64_t k = 0; k < 100; ++k) {
            const float cos_o = 0.05f + 0.95f * static_cast<float>(uniform(1, k));
            const fl::V3 wo = fdir(cos_o, 0.0f);
            const float s = c.alpha * (1.0f + kappa) * 2.0f * static_cast<float>(uniform(2, k));
            const float phi = 2.0f * kPi * static_cast<float>(uniform(3, k));
            const fl::V3 wi =
                mf::reflect(wo, mf::normalize({s * std::cos(phi), s * std::sin(phi), 1.0f}));
            if (!(wi.z > 1e-3f)) continue;
            float ref_f[3], ref, got_f[3], got;
            fl::cap_integral({c.alpha, sin2, &fresnel}, wo, wi, ref_f, ref, 1e-9);
            fl::slope_integral(c.alpha, sin2, &fresnel, wo, wi, got_f, got);
            if (!(ref > 1e-7f)) continue;
            worst = std::max(worst, static_cast<double>(std::fabs(got - ref) / ref));
            worst_f =
                std::max(worst_f, static_cast<double>(std::fabs(got_f[1] / got - ref_f[1] / ref)));
        }
    }
    // Measured: 9.5e-4 and 5.1e-4 (the tiny regions of alpha 0.01, gamma 1).
    EXPECT_LT(worst, 2e-3);
    EXPECT_LT(worst_f, 1.5e-3);
}

TEST(FlakeTables, LobeMassMatchesTheVisibleNormals) {
    // M(wo) = E[A(r.z) 1[r.z > 0]] over wo's visible normals: a 1200^2 stratified grid of the
    // visible normals (the definition), from normal incidence to grazing, narrow and wide cones.
    for (float alpha : {0.05f, 0.15f, 0.35f})
        for (float gamma : {3.0f, 30.0f})
            for (float cos_o : {0.9f, 0.5f, 0.1f, 0.02f}) {
                const double sin2 = std::pow(std::sin(0.5 * gamma * M_PI / 180.0), 2.0);
                const fl::V3 wo = fdir(cos_o, 0.0f);
                constexpr int kGrid = 1200;
                double sum = 0.0;
                for (int a = 0; a < kGrid; ++a)
                    for (int b = 0; b < kGrid; ++b) {
                        const fl::V3 m = mf::ggx_sample_visible(
                            wo, alpha, alpha, static_cast<float>((a + 0.5) / kGrid),
                            static_cast<float>((b + 0.5) / kGrid));
                        const fl::V3 r = mf::reflect(wo, m);
                        if (r.z > 0.0f) sum += fl::cone_fraction_above(r.z, sin2);
                    }
                const double grid = sum / (static_cast<double>(kGrid) * kGrid);
                // The grid's own error: the horizon cuts its cells (about 1 / 1200 of the mass
                // lies in the cells it crosses at grazing, and they are half counted).
                EXPECT_NEAR(fl::lobe_mass(alpha, sin2, wo), grid, 5e-4)
                    << "alpha " << alpha << " gamma " << gamma << " cos_o " << cos_o;
            }
}

/** The smooth lobe of (alpha, gamma) built through `cache`. */
fl::SmoothLobe lobe_through(const fl::TableCache& cache, const fl::FresnelTable& fresnel,
                            float alpha, float gamma_deg) {
    fl::SmoothLobe lobe;
    lobe.init(alpha, gamma_deg * kPi / 180.0f, &fresnel, &cache);
    return lobe;
}

TEST(FlakeTables, CachedTableIsTheBuiltOneBitForBit) {
    TempDir dir("flake_cache");
    const fl::TableCache cache(dir.path().string(), 64u << 20);
    const fl::FresnelTable fresnel = dielectric();
    // A material no other test builds (the process shares tables between equal materials).
    const fl::SmoothLobe built = lobe_through(cache, fresnel, 0.123f, 4.5f);
    ASSERT_FALSE(built.from_cache);
    ASSERT_TRUE(built.table);
    const fl::SmoothLobe cached = lobe_through(cache, fresnel, 0.123f, 4.5f);
    ASSERT_TRUE(cached.from_cache);
    ASSERT_NE(built.table.get(), cached.table.get()) << "the second one was read from disk";
    const std::vector<uint8_t> a = built.pack(), b = cached.pack();
    ASSERT_EQ(a.size(), b.size());
    EXPECT_EQ(std::memcmp(a.data(), b.data(), a.size()), 0);
    EXPECT_EQ(std::memcmp(built.table->data.data(), cached.table->data.data(),
                          built.table->data.size() * sizeof(float)),
              0);
    EXPECT_EQ(std::memcmp(built.valid, cached.valid, sizeof(built.valid)), 0);
    // And the lobes they make are the same, bit for bit.
    const fl::V3 wo = fdir(0.6f, 0.3f);
    for (int k = 0; k < 50; ++k) {
        fl::V3 wi;
        if (!fl::sample_smooth(built, wo, static_cast<float>(uniform(4, k)),
                               static_cast<float>(uniform(5, k)), wi))
            continue;
        float f0[3], f1[3], p0, p1;
        fl::eval_smooth(built, wo, built.valid_fraction(wo.z), wi, f0, p0);
        fl::eval_smooth(cached, wo, cached.valid_fraction(wo.z), wi, f1, p1);
        EXPECT_EQ(std::memcmp(f0, f1, sizeof(f0)), 0);
        EXPECT_EQ(p0, p1);
    }
    // A table a rough coat makes is cached the same way.
    fl::Coat c0, c1;
    c0.init(true, 1.6f, 0.27f, &cache);
    c1.init(true, 1.6f, 0.27f, &cache);
    EXPECT_EQ(std::memcmp(c0.albedo, c1.albedo, sizeof(c0.albedo)), 0);
    // And the sparse flakes' scale: stored by the first, read by the second, equal to one built
    // without the cache.
    const auto files = [&] {
        return std::distance(fs::directory_iterator(dir.path()), fs::directory_iterator());
    };
    const auto before = files();
    fl::SparseAlbedo s0, s1, s2;
    s0.init(0.123f, 0.05f, fresnel, true, &cache);
    EXPECT_EQ(files(), before + 1) << "the table was stored";
    s1.init(0.123f, 0.05f, fresnel, true, &cache);
    s2.init(0.123f, 0.05f, fresnel, true, nullptr);
    EXPECT_FALSE(s0.flat);
    EXPECT_EQ(s1.flat, s0.flat);
    EXPECT_EQ(std::memcmp(s0.scale, s1.scale, sizeof(s0.scale)), 0);
    EXPECT_EQ(std::memcmp(s0.tail, s1.tail, sizeof(s0.tail)), 0);
    EXPECT_EQ(std::memcmp(s0.scale, s2.scale, sizeof(s0.scale)), 0);
}

TEST(FlakeTables, DamagedForeignAndStaleFilesAreRebuilt) {
    TempDir dir("flake_cache_damaged");
    const fl::TableCache cache(dir.path().string(), 64u << 20);
    fl::TableKey key("test table");
    key.add(1.5);
    const std::vector<uint8_t> table = {1, 2, 3, 4, 5, 6, 7, 8, 9};
    cache.store(key, table);
    std::vector<uint8_t> back;
    ASSERT_TRUE(cache.load(key, back));
    EXPECT_EQ(back, table);
    const std::string path = cache.path_of(key);
    // One byte of the table flipped: the checksum refuses it.
    {
        std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
        f.seekp(-10, std::ios::end);
        f.put('\x7f');
    }
    EXPECT_FALSE(cache.load(key, back));
    // Truncated: refused.
    fs::resize_file(path, fs::file_size(path) / 2);
    EXPECT_FALSE(cache.load(key, back));
    // Another key's file under this name (a hash collision, or another version of the plugin):
    // the stored key differs, so it is refused.
    fl::TableKey other("test table");
    other.add(2.5);
    cache.store(other, table);
    fs::copy_file(cache.path_of(other), path, fs::copy_options::overwrite_existing);
    EXPECT_FALSE(cache.load(key, back));
    // The plugin's version is part of every key.
    EXPECT_NE(std::string(fl::plugin_version()), "");
    const std::string head(key.bytes().begin(), key.bytes().end());
    EXPECT_NE(head.find(fl::plugin_version()), std::string::npos);
    // A smooth lobe whose cached file is damaged rebuilds the same table.
    const fl::FresnelTable fresnel = dielectric();
    const fl::SmoothLobe built = lobe_through(cache, fresnel, 0.131f, 2.5f);
    for (const auto& e : fs::directory_iterator(dir.path())) {
        if (e.path().extension() != ".tab" || fs::file_size(e.path()) < 100000) continue;
        std::fstream f(e.path(), std::ios::in | std::ios::out | std::ios::binary);
        f.seekp(5000);
        f.put('\x55');
    }
    const fl::SmoothLobe again = lobe_through(cache, fresnel, 0.131f, 2.5f);
    EXPECT_FALSE(again.from_cache);
    EXPECT_EQ(built.pack(), again.pack());
    EXPECT_TRUE(lobe_through(cache, fresnel, 0.131f, 2.5f).from_cache) << "rewritten";
}

TEST(FlakeTables, ProcessesWritingAtOnceLeaveACompleteTable) {
    // Eight processes store the same 4 MB table at once while this one reads it: every read sees
    // the whole table or none (writers rename complete temporary files over the final name).
    TempDir dir("flake_cache_concurrent");
    const fl::TableCache cache(dir.path().string(), 256u << 20);
    fl::TableKey key("concurrent table");
    std::vector<uint8_t> table(4u << 20);
    for (std::size_t i = 0; i < table.size(); ++i) table[i] = static_cast<uint8_t>(hash2(7, i));
    std::vector<pid_t> children;
    for (int p = 0; p < 8; ++p) {
        const pid_t pid = fork();
        ASSERT_GE(pid, 0);
        if (pid == 0) {
            for (int r = 0; r < 5; ++r) cache.store(key, table);
            _exit(0);
        }
        children.push_back(pid);
    }
    int complete = 0, absent = 0;
    std::vector<uint8_t> back;
    for (int r = 0; r < 200; ++r) {
        if (cache.load(key, back)) {
            ASSERT_EQ(back, table) << "a partial or mixed table was read";
            ++complete;
        } else {
            ++absent;
        }
    }
    for (const pid_t pid : children) {
        int status = 0;
        waitpid(pid, &status, 0);
        EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    }
    ASSERT_TRUE(cache.load(key, back));
    EXPECT_EQ(back, table);
    // No temporary file is left behind.
    for (const auto& e : fs::directory_iterator(dir.path()))
        EXPECT_EQ(e.path().extension(), ".tab") << e.path();
    EXPECT_GT(complete + absent, 0);
}

TEST(FlakeTables, SizeBoundKeepsTheMostRecentlyUsed) {
    TempDir dir("flake_cache_bound");
    constexpr uint64_t kBound = 3u << 20;
    const fl::TableCache cache(dir.path().string(), kBound);
    const std::vector<uint8_t> table(512u << 10, 3);
    const auto key_of = [](int i) {
        fl::TableKey key("bounded table");
        key.add(i);
        return key;
    };
    std::vector<uint8_t> back;
    for (int i = 0; i < 12; ++i) {
        cache.store(key_of(i), table);
        // Table 0 is read after every store: it stays the most recently used.
        EXPECT_TRUE(cache.load(key_of(0), back)) << "after storing " << i;
        uint64_t total = 0;
        for (const auto& e : fs::directory_iterator(dir.path())) total += fs::file_size(e.path());
        EXPECT_LE(total, kBound) << "after storing " << i;
    }
    EXPECT_TRUE(cache.load(key_of(11), back)) << "the newest table";
    EXPECT_FALSE(cache.load(key_of(1), back)) << "an old, unused table was trimmed";
}

TEST(FlakeTables, EnvironmentChoosesTheCacheDirectory) {
    const char* before = std::getenv("SPANGLE_FLAKE_CACHE");
    const std::string saved = before ? before : "";
    setenv("SPANGLE_FLAKE_CACHE", "off", 1);
    EXPECT_FALSE(fl::TableCache::from_environment().enabled());
    setenv("SPANGLE_FLAKE_CACHE", "/some/where", 1);
    EXPECT_EQ(fl::TableCache::from_environment().dir(), "/some/where");
    setenv("SPANGLE_FLAKE_CACHE_MB", "17", 1);
    EXPECT_EQ(fl::TableCache::from_environment().max_bytes(), 17u << 20);
    unsetenv("SPANGLE_FLAKE_CACHE_MB");
    // Values that are not what they name are said, not taken for something else.
    const char* threads_before = std::getenv("SPANGLE_FLAKE_THREADS");
    const std::string threads_saved = threads_before ? threads_before : "";
    for (const char* bad : {"4x", "-2", "0", "two"}) {
        setenv("SPANGLE_FLAKE_THREADS", bad, 1);
        std::vector<std::string> said;
        fl::TableCache::from_environment([&](const std::string& m) { said.push_back(m); });
        ASSERT_EQ(said.size(), 1u) << bad;
        EXPECT_NE(said[0].find("SPANGLE_FLAKE_THREADS='" + std::string(bad) + "'"),
                  std::string::npos)
            << said[0];
        EXPECT_GE(fl::table_threads(), 1) << bad;
        EXPECT_LE(fl::table_threads(), 16) << bad;
    }
    setenv("SPANGLE_FLAKE_THREADS", "3", 1);
    std::vector<std::string> said;
    fl::TableCache::from_environment([&](const std::string& m) { said.push_back(m); });
    EXPECT_TRUE(said.empty());
    EXPECT_EQ(fl::table_threads(), 3);
    setenv("SPANGLE_FLAKE_CACHE_MB", "12MB", 1);
    fl::TableCache::from_environment([&](const std::string& m) { said.push_back(m); });
    ASSERT_EQ(said.size(), 1u);
    EXPECT_NE(said[0].find("SPANGLE_FLAKE_CACHE_MB='12MB'"), std::string::npos) << said[0];
    unsetenv("SPANGLE_FLAKE_CACHE_MB");
    if (threads_before)
        setenv("SPANGLE_FLAKE_THREADS", threads_saved.c_str(), 1);
    else
        unsetenv("SPANGLE_FLAKE_THREADS");
    if (before)
        setenv("SPANGLE_FLAKE_CACHE", saved.c_str(), 1);
    else
        unsetenv("SPANGLE_FLAKE_CACHE");
}

}  // namespace
}  // namespace spangle::test::flake_tables
