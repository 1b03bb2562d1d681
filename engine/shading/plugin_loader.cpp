#include "shading/plugin_loader.h"

#include <unistd.h>

#include "core/files.h"
#include "core/text.h"

#include <dlfcn.h>
#include <elf.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>

namespace fs = std::filesystem;

namespace spangle {

LoadedPlugin::~LoadedPlugin() {
    if (handle_) dlclose(handle_);
}

const SpangleMaterialModel_v3* LoadedPlugin::model(const std::string& name) const {
    for (uint32_t i = 0; i < table_->model_count; ++i)
        if (name == table_->models[i].name) return &table_->models[i];
    return nullptr;
}

std::vector<std::string> LoadedPlugin::model_names() const {
    std::vector<std::string> names;
    for (uint32_t i = 0; i < table_->model_count; ++i) names.emplace_back(table_->models[i].name);
    return names;
}

std::vector<std::string> env_plugin_dirs() {
    std::vector<std::string> dirs;
    if (const char* env = std::getenv("SPANGLE_PLUGIN_PATH"); env && *env) {
        std::string s(env);
        std::size_t start = 0;
        while (start <= s.size()) {
            const std::size_t end = std::min(s.find(':', start), s.size());
            if (end > start) dirs.push_back(s.substr(start, end - start));
            start = end + 1;
        }
    }
    return dirs;
}

std::vector<std::string> plugin_search_path(const std::vector<std::string>& cli_dirs) {
    std::vector<std::string> dirs(cli_dirs);
    for (std::string& d : env_plugin_dirs()) dirs.push_back(std::move(d));
    const std::string exe = executable_dir();
    if (!exe.empty()) {
        dirs.push_back((fs::path(exe) / "plugins").string());
        dirs.push_back(
            (fs::path(exe) / ".." / "lib" / "spangle" / "plugins").lexically_normal().string());
    }
    // Each folder once (the first place it takes): `--plugin-path build/plugins` beside the
    // executable's own was listed twice.
    std::vector<std::string> once;
    std::vector<std::string> seen;
    for (const std::string& d : dirs) {
        std::error_code ec;
        fs::path key = fs::weakly_canonical(fs::absolute(d, ec), ec);
        if (ec) key = fs::path(d).lexically_normal();
        if (std::find(seen.begin(), seen.end(), key.string()) != seen.end()) continue;
        seen.push_back(key.string());
        once.push_back(d);
    }
    return once;
}

namespace {

std::string file_name_for(const std::string& name) {
    return "libspangle_" + name + ".so";
}

/** What is wrong with one parameter's description (the host would hand create() values its
 *  own schema forbids, or refuse every value a scene gives); empty when it is fine. */
std::string param_problem(const SpangleParamDesc_v3& d) {
    const std::string name = d.name;
    const bool snake = std::islower(static_cast<unsigned char>(name[0])) &&
                       std::all_of(name.begin(), name.end(), [](char c) {
                           return std::islower(static_cast<unsigned char>(c)) ||
                                  std::isdigit(static_cast<unsigned char>(c)) || c == '_';
                       });
    if (!snake) return "is not a snake_case name (a-z, 0-9 and _, starting with a letter)";
    const int type = static_cast<int>(d.type);
    if (type < SPANGLE_PARAM_FLOAT || type > SPANGLE_PARAM_VEC3)
        return fmt::format("has type {}, which is not a SpangleParamType", type);
    const bool numeric = d.type != SPANGLE_PARAM_STRING && d.type != SPANGLE_PARAM_BOOL;
    if ((d.flags & SPANGLE_PARAM_TEXTURABLE) && d.type != SPANGLE_PARAM_FLOAT &&
        d.type != SPANGLE_PARAM_COLOR)
        return "is marked texturable, which only FLOAT and COLOR parameters may be";
    if (d.type == SPANGLE_PARAM_STRING) {
        if (!d.default_string) return "is a STRING without a default_string";
        if (d.choices) {
            const std::string choices = d.choices;
            bool found = false;
            for (std::size_t at = 0; at <= choices.size();) {
                const std::size_t bar = std::min(choices.find('|', at), choices.size());
                found = found || (bar - at == std::strlen(d.default_string) &&
                                  choices.compare(at, bar - at, d.default_string) == 0);
                at = bar + 1;
            }
            if (!found)
                return fmt::format("has the default '{}', which is not one of its choices ({})",
                                   d.default_string, choices);
        }
        return {};
    }
    if (d.type == SPANGLE_PARAM_BOOL) {
        if (d.default_value[0] != 0.0 && d.default_value[0] != 1.0)
            return fmt::format("is a BOOL with the default {}, expected 0 or 1",
                               d.default_value[0]);
        return {};
    }
    if (numeric && !(d.min_value <= d.max_value))
        return fmt::format("has the range [{}, {}], whose minimum is not at most its maximum",
                           d.min_value, d.max_value);
    const int channels = d.type == SPANGLE_PARAM_COLOR || d.type == SPANGLE_PARAM_VEC3 ? 3 : 1;
    for (int c = 0; c < channels; ++c) {
        const double v = d.default_value[c];
        if (!(v >= d.min_value && v <= d.max_value))
            return fmt::format("has the default {} outside its range [{}, {}]", v, d.min_value,
                               d.max_value);
        if (d.type == SPANGLE_PARAM_INT && v != std::floor(v))
            return fmt::format("is an INT with the default {}, which is not a whole number", v);
    }
    return {};
}

/** Sanity checks of a table the host is about to trust; returns an empty string when fine. */
std::string table_problem(const SpangleMaterialPlugin_v3& t) {
    if (!t.name || !*t.name) return "it has no name";
    if (t.model_count == 0 || !t.models) return "it offers no material model";
    for (uint32_t i = 0; i < t.model_count; ++i) {
        const SpangleMaterialModel_v3& m = t.models[i];
        if (!m.name || !*m.name) return fmt::format("model #{} has no name", i);
        if (!m.create || !m.destroy || !m.prepare || !m.eval || !m.sample)
            return fmt::format("model '{}' lacks a kernel (create, destroy, prepare, eval, sample)",
                               m.name);
        if (m.closure_size == 0 || m.closure_size > 4096)
            return fmt::format("model '{}' declares closure_size {}, expected 1..4096", m.name,
                               m.closure_size);
        if (m.param_count > 0 && !m.params)
            return fmt::format("model '{}' has no parameter table", m.name);
        for (uint32_t k = 0; k < m.param_count; ++k) {
            if (!m.params[k].name || !*m.params[k].name)
                return fmt::format("model '{}' parameter #{} has no name", m.name, k);
            if (std::string why = param_problem(m.params[k]); !why.empty())
                return fmt::format("model '{}' parameter '{}' {}", m.name, m.params[k].name, why);
            for (uint32_t j = 0; j < k; ++j)
                if (std::strcmp(m.params[j].name, m.params[k].name) == 0)
                    return fmt::format("model '{}' has two parameters called '{}'", m.name,
                                       m.params[k].name);
        }
        for (uint32_t j = 0; j < i; ++j)
            if (std::strcmp(t.models[j].name, m.name) == 0)
                return fmt::format("it has two models called '{}'", m.name);
    }
    return {};
}

/** Checks a library before dlopen maps it (`shown`: the path its messages name): a regular file (a
 * pipe hangs dlopen), an ELF file for this machine, with every segment the loader maps lying inside
 * the file (a truncated library is mapped past its end and dies with SIGBUS on first touch). Throws
 * SpangleError. */
void check_library_file(const std::string& path, const std::string& shown) {
    std::error_code ec;
    if (!fs::is_regular_file(path, ec))
        throw_error("plugin '{}' is not a regular file (a folder, a device or a pipe)", shown);
    const auto size = static_cast<uint64_t>(fs::file_size(path, ec));
    std::ifstream in(path, std::ios::binary);
    Elf64_Ehdr eh{};
    if (ec || !in.read(reinterpret_cast<char*>(&eh), sizeof(eh)) ||
        std::memcmp(eh.e_ident, ELFMAG, SELFMAG) != 0)
        throw_error("plugin '{}' is not a shared library (no ELF header)", shown);
    if (eh.e_ident[EI_CLASS] != ELFCLASS64 || eh.e_machine != EM_X86_64 || eh.e_type != ET_DYN)
        throw_error("plugin '{}' is not a 64-bit x86-64 shared library", shown);
    if (eh.e_phentsize != sizeof(Elf64_Phdr) || eh.e_phoff > size ||
        static_cast<uint64_t>(eh.e_phnum) * sizeof(Elf64_Phdr) > size - eh.e_phoff)
        throw_error("plugin '{}' is damaged: its program headers lie outside the file", shown);
    // The section headers come last: a file cut short anywhere (a copy still being written)
    // loses them, even when the mapped segments happen to be whole.
    if (eh.e_shoff > size || static_cast<uint64_t>(eh.e_shnum) * eh.e_shentsize > size - eh.e_shoff)
        throw_error(
            "plugin '{}' is truncated: its section headers end at byte {}, the file "
            "has {} (rebuild or copy it again)",
            shown, eh.e_shoff + static_cast<uint64_t>(eh.e_shnum) * eh.e_shentsize, size);
    in.seekg(static_cast<std::streamoff>(eh.e_phoff));
    for (int i = 0; i < eh.e_phnum; ++i) {
        Elf64_Phdr ph{};
        if (!in.read(reinterpret_cast<char*>(&ph), sizeof(ph)))
            throw_error("plugin '{}' is damaged: cannot read its program headers", shown);
        if (ph.p_type == PT_LOAD && (ph.p_offset > size || ph.p_filesz > size - ph.p_offset))
            throw_error(
                "plugin '{}' is truncated: a segment needs {} bytes, the file has {} "
                "(rebuild or copy it again)",
                shown, ph.p_offset + ph.p_filesz, size);
    }
}

/** Whether `address` lies in an executable mapping of this process (a symbol exported as data
 *  and called as a function would crash). */
bool in_executable_mapping(const void* address) {
    const auto a = reinterpret_cast<uintptr_t>(address);
    std::ifstream maps("/proc/self/maps");
    std::string line;
    while (std::getline(maps, line)) {
        unsigned long lo = 0, hi = 0;
        char perms[5] = {};
        if (std::sscanf(line.c_str(), "%lx-%lx %4s", &lo, &hi, perms) != 3) continue;
        if (a >= lo && a < hi) return perms[2] == 'x';
    }
    return false;
}

}  // namespace

std::shared_ptr<LoadedPlugin> PluginLoader::open_file(const std::string& path,
                                                      const std::string& expected_name,
                                                      const std::string& shown_path) {
    // Messages name the file the user has (a private copy's name would mean nothing to them).
    const std::string& shown = shown_path.empty() ? path : shown_path;
    check_library_file(path, shown);
    dlerror();
    void* handle = nullptr;
    try {
        handle = dlopen(path.c_str(), RTLD_NOW | RTLD_LOCAL);
    } catch (const std::exception& e) {
        throw_error("plugin '{}' threw while it was loaded (a static initialiser): {}", shown,
                    e.what());
    } catch (...) {
        throw_error("plugin '{}' threw while it was loaded (a static initialiser)", shown);
    }
    if (!handle) {
        const char* why = dlerror();
        throw_error("cannot open plugin '{}': {}", shown, why ? why : "unknown dlopen error");
    }
    // From here on the handle is owned by a guard so that every error path closes it.
    std::unique_ptr<void, int (*)(void*)> guard(handle, dlclose);
    dlerror();
    void* sym = dlsym(handle, SPANGLE_MATERIAL_ENTRY_POINT);
    if (!sym) {
        const char* why = dlerror();
        throw_error(
            "'{}' is not a Spangle plugin: it has no entry point '{}' ({}; in C++ the entry "
            "point must be declared extern \"C\" and exported, e.g. with SPANGLE_PLUGIN_EXPORT)",
            shown, SPANGLE_MATERIAL_ENTRY_POINT, why ? why : "symbol is null");
    }
    if (!in_executable_mapping(sym))
        throw_error("'{}' is not a Spangle plugin: its '{}' is data, not a function", shown,
                    SPANGLE_MATERIAL_ENTRY_POINT);
    SpangleMaterialEntry_v3 entry;
    static_assert(sizeof(entry) == sizeof(sym));
    std::memcpy(&entry, &sym, sizeof(entry));
    const SpangleMaterialPlugin_v3* table = nullptr;
    try {
        table = entry(SPANGLE_MATERIAL_ABI_VERSION);
    } catch (const std::exception& e) {
        throw_error("plugin '{}': its entry point threw (a plugin must not throw): {}", shown,
                    e.what());
    } catch (...) {
        throw_error("plugin '{}': its entry point threw (a plugin must not throw)", shown);
    }
    if (!table)
        throw_error("plugin '{}' refused this host's material ABI version {}", shown,
                    SPANGLE_MATERIAL_ABI_VERSION);
    if (table->abi_version != SPANGLE_MATERIAL_ABI_VERSION)
        throw_error(
            "plugin '{}' was built for material ABI version {}, but this spangle uses "
            "version {}: rebuild the plugin against this spangle's plugin.h",
            shown, table->abi_version, SPANGLE_MATERIAL_ABI_VERSION);
    if (table->struct_size != sizeof(SpangleMaterialPlugin_v3))
        throw_error("plugin '{}' has a plugin table of {} bytes, expected {}: ABI mismatch", shown,
                    table->struct_size, sizeof(SpangleMaterialPlugin_v3));
    if (const std::string p = table_problem(*table); !p.empty())
        throw_error("plugin '{}' is malformed: {}", shown, p);
    if (!expected_name.empty() && expected_name != table->name)
        throw_error("plugin file '{}' calls itself '{}', expected '{}'", shown, table->name,
                    expected_name);
    guard.release();
    return std::make_shared<LoadedPlugin>(shown_path.empty() ? path : shown_path, handle, table);
}

std::shared_ptr<LoadedPlugin> PluginLoader::open_copy(const std::string& path,
                                                      const std::string& name) {
    const fs::path copy =
        fs::temp_directory_path() /
        fmt::format("spangle-{}-{}-{}", ::getpid(), ++copies_, fs::path(path).filename().string());
    std::error_code ec;
    fs::copy_file(path, copy, fs::copy_options::overwrite_existing, ec);
    if (ec) throw_error("cannot copy plugin '{}' from {}: {}", name, path, ec.message());
    std::shared_ptr<LoadedPlugin> plugin;
    try {
        plugin = open_file(copy.string(), name, path);
    } catch (const SpangleError&) {
        fs::remove(copy, ec);
        throw;
    }
    fs::remove(copy, ec);  // the mapping stays; nothing is left behind
    return plugin;
}

std::shared_ptr<LoadedPlugin> PluginLoader::open(const std::string& name, const FileLoc& where) {
    if (auto it = cache_.find(name); it != cache_.end() && reopen_changed) {
        // Watch sessions: a library put since in a folder searched before this one's is the one
        // a fresh render opens: opened afresh (the session kept the old one for good).
        const std::string file = file_name_for(name);
        for (const auto& dir : dirs_) {
            const fs::path candidate = fs::path(dir) / file;
            std::error_code ec;
            if (!fs::exists(candidate, ec)) continue;
            if (!fs::equivalent(candidate, it->second->path(), ec)) {
                cache_.erase(it);
                identity_.erase(name);
            }
            break;
        }
    }
    if (auto it = cache_.find(name); it != cache_.end()) {
        if (!reopen_changed) return it->second;
        const std::string& path = it->second->path();
        const std::string id = file_identity(path);
        if (id == identity_[name]) return it->second;
        // Rebuilt since it was opened: open the new file through a private copy.
        std::shared_ptr<LoadedPlugin> plugin;
        try {
            plugin = open_copy(path, name);
        } catch (const SpangleError& e) {
            throw SpangleError(where, e.what());
        }
        it->second = plugin;
        identity_[name] = id;
        return plugin;
    }
    const bool valid_name = !name.empty() && name.find_first_of("/\\. ") == std::string::npos;
    if (!valid_name)
        throw_error(where,
                    "plugin name '{}' is not valid: use the plugin's short name, e.g. 'smooth'",
                    name);
    const std::string file = file_name_for(name);
    for (const auto& dir : dirs_) {
        const fs::path candidate = fs::path(dir) / file;
        std::error_code ec;
        if (!fs::exists(candidate, ec)) {
            if (fs::is_symlink(fs::symlink_status(candidate, ec)))
                throw_error(where, "plugin '{}': {} is a symbolic link to {}, which does not exist",
                            name, candidate.string(), fs::read_symlink(candidate, ec).string());
            continue;
        }
        try {
            const std::string id = file_identity(candidate.string());
            // Watched plugins are mapped from a private copy from the first load on: a rebuild
            // that writes the library in place (cp, install) would change the pages under the
            // running process (SIGBUS), where a rename or a new file leaves them alone.
            auto plugin = copy_on_first_open ? open_copy(candidate.string(), name)
                                             : open_file(candidate.string(), name);
            cache_[name] = plugin;
            identity_[name] = id;
            return plugin;
        } catch (const SpangleError& e) {
            throw SpangleError(where, e.what());
        }
    }
    std::vector<std::string> known;  // the plugin names on the path, for a suggestion
    for (const auto& f : discover()) {
        const std::string stem = fs::path(f).stem().string();
        known.push_back(stem.substr(std::string("libspangle_").size()));
    }
    throw_error(where, "plugin '{}' not found (no {} in {}){}", name, file,
                dirs_.empty() ? std::string("an empty plugin path")
                              : fmt::format("{}", fmt::join(dirs_, ", ")),
                did_you_mean(name, known));
}

std::vector<std::string> PluginLoader::discover() const {
    std::vector<std::string> found;
    std::set<std::string> names;
    for (const auto& dir : dirs_) {
        std::error_code ec;
        std::vector<fs::path> files;
        for (const auto& e : fs::directory_iterator(dir, ec)) files.push_back(e.path());
        std::sort(files.begin(), files.end());
        for (const auto& p : files) {
            const std::string f = p.filename().string();
            if (f.rfind("libspangle_", 0) != 0 || p.extension() != ".so") continue;

            if (names.insert(f).second) found.push_back(p.string());
        }
    }
    return found;
}

std::vector<std::string> PluginLoader::searched_before(const std::string& name,
                                                       const std::string& path) const {
    std::vector<std::string> out;
    const std::string file = file_name_for(name);
    for (const auto& dir : dirs_) {
        const fs::path candidate = fs::path(dir) / file;
        std::error_code ec;
        if (fs::exists(candidate, ec)) {
            if (fs::equivalent(candidate, path, ec) || candidate == fs::path(path)) break;
            continue;  // another file before it (opened as it was, or changed since): not absent
        }
        if (candidate == fs::path(path)) break;
        out.push_back(candidate.string());
    }
    return out;
}

std::vector<std::string> PluginLoader::opened_files() const {
    std::vector<std::string> files;
    for (const auto& [name, plugin] : cache_) files.push_back(plugin->path());
    return files;
}

std::vector<std::string> PluginLoader::opened() const {
    std::vector<std::string> names;
    for (const auto& [name, plugin] : cache_) names.push_back(name);
    return names;
}

}  // namespace spangle
