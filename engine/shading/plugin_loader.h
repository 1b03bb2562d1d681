#pragma once
// Finding and opening material plugins. A plugin named N is the file libspangle_N.so in the first
// directory of the search path that has it: every --plugin-path given, then each entry of
// $SPANGLE_PLUGIN_PATH (colon-separated), then the plugins/ directory beside the spangle binary
// (and ../lib/spangle/plugins for an installed tree). A plugin is opened when a scene first
// names it and closed when the last material using it is gone.

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/error.h"
#include "spangle/plugin.h"

namespace spangle {

/** An opened plugin library; dlclose()s on destruction. */
class LoadedPlugin {
public:
    LoadedPlugin(std::string path, void* handle, const SpangleMaterialPlugin_v3* table)
        : path_(std::move(path)), handle_(handle), table_(table) {}
    ~LoadedPlugin();
    LoadedPlugin(const LoadedPlugin&) = delete;
    LoadedPlugin& operator=(const LoadedPlugin&) = delete;

    const std::string& path() const { return path_; }
    const SpangleMaterialPlugin_v3& table() const { return *table_; }
    /** The model called `name`, or nullptr. */
    const SpangleMaterialModel_v3* model(const std::string& name) const;
    /** Model names, for messages. */
    std::vector<std::string> model_names() const;

private:
    std::string path_;
    void* handle_;
    const SpangleMaterialPlugin_v3* table_;
};

/** The search path in order: CLI dirs, $SPANGLE_PLUGIN_PATH, then the directories beside the
 *  running binary. */
std::vector<std::string> plugin_search_path(const std::vector<std::string>& cli_dirs);

/** The folders $SPANGLE_PLUGIN_PATH lists (colon-separated, empty entries skipped), in order. */
std::vector<std::string> env_plugin_dirs();

/** Opens plugins by name from a search path and caches them. */
class PluginLoader {
public:
    explicit PluginLoader(std::vector<std::string> search_path) : dirs_(std::move(search_path)) {}

    /** Opens (or returns the cached) plugin `name`. Errors are reported at `where`. */
    std::shared_ptr<LoadedPlugin> open(const std::string& name, const FileLoc& where);

    /** Opens one file as a plugin; throws SpangleError naming the file and what is wrong.
     *  `shown_path`, when given, is the path the plugin reports (the file opened may be a
     *  private copy of it). */
    static std::shared_ptr<LoadedPlugin> open_file(const std::string& path,
                                                   const std::string& expected_name,
                                                   const std::string& shown_path = {});

    /** Watch sessions: open() reopens a cached plugin whose file changed since it was opened.
     *  dlopen() returns the handle it already has for a path, so the new file is opened through
     *  a private copy (removed at once; the mapping stays); instances of the old library keep it
     *  loaded until they are destroyed. */
    bool reopen_changed = false;
    /** Watch mode: the first open maps a private copy too, so that a rebuild writing the library
     *  in place (cp, install) cannot change the pages under the running process (SIGBUS). */
    bool copy_on_first_open = false;

    /** Every libspangle_*.so on the search path, first occurrence of each name, in order. */
    std::vector<std::string> discover() const;

    const std::vector<std::string>& search_path() const { return dirs_; }
    /** Where plugin `name` would be found before `path`, the file it was opened from: its file
     *  in each folder searched before path's folder, none of which exists now (a watch session
     *  watches them: a library put back there, after one was removed and a later folder's copy
     *  taken, is opened again). */
    std::vector<std::string> searched_before(const std::string& name,
                                             const std::string& path) const;
    /** Names of plugins opened so far, for --stats. */
    std::vector<std::string> opened() const;
    /** The files of the plugins opened so far, in the order of their names. */
    std::vector<std::string> opened_files() const;

private:
    /** open_file() of a private copy of `path` (named as `path` in messages and by the plugin). */
    std::shared_ptr<LoadedPlugin> open_copy(const std::string& path, const std::string& name);
    std::vector<std::string> dirs_;
    std::map<std::string, std::shared_ptr<LoadedPlugin>> cache_;
    std::map<std::string, std::string> identity_;  ///< file identity when each was opened
    int copies_ = 0;                               ///< private copies made so far
};

}  // namespace spangle
