// The look-development loop, measured from outside: how long from saving an edit to the first new
// image on disk, beside the cold start of the same scene, and whether memory grows over many
// reloads. Runs `spangle render SCENE --watch` on a temporary copy of the scene's folder tree and
// edits it the way a user would (whole-file saves renamed into place):
//   material   the first number in the first material's params, a new value each time
//   transform  the translate of the first subdivided object (else the first object)
//   cage       a comment appended to that object's mesh file (re-read, re-subdivided)
// A new image is "written" when both the EXR and its PNG preview have been renamed into place.
// The first one after a save is the reduced-resolution preview pass, the second the first full
// pass (1 spp).
//
//   spangle_reload_bench SCENE [--spangle PATH] [--plugin-path DIR] [--threads N]
//                              [--size WxH] [--repeats N] [--reloads N]
// Defaults: the spangle and plugins beside this binary, 5 repeats, 100 reloads for memory.

#include <OpenImageIO/imageio.h>
#include <fcntl.h>
#include <fmt/format.h>
#include <poll.h>
#include <spawn.h>
#include <sys/inotify.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

extern char** environ;

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

[[noreturn]] void die(const std::string& msg) {
    fmt::print(stderr, "spangle_reload_bench: {}\n", msg);
    std::exit(1);
}

std::string read_file(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    if (!in) die(fmt::format("cannot read {}", p.string()));
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

/** Saves like an editor that writes a temporary file and renames it over the old one. */
void save(const fs::path& p, const std::string& text) {
    const fs::path tmp = p.string() + ".bench-tmp";
    {
        std::ofstream out(tmp, std::ios::binary);
        out << text;
    }
    fs::rename(tmp, p);
}

double seconds_since(Clock::time_point t) {
    return std::chrono::duration<double>(Clock::now() - t).count();
}

/** The watch process, its stdout, and inotify on its output folder. */
class Watched {
public:
    Watched(const std::vector<std::string>& args, const fs::path& out_dir) {
        int fds[2];
        if (::pipe(fds) != 0) die("pipe failed");
        posix_spawn_file_actions_t fa;
        posix_spawn_file_actions_init(&fa);
        posix_spawn_file_actions_adddup2(&fa, fds[1], STDOUT_FILENO);
        posix_spawn_file_actions_addopen(&fa, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
        posix_spawn_file_actions_addclose(&fa, fds[0]);
        std::vector<char*> argv;
        for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
        argv.push_back(nullptr);
        notify_ = inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
        inotify_add_watch(notify_, out_dir.c_str(), IN_MOVED_TO);
        started_ = Clock::now();
        if (posix_spawn(&pid_, argv[0], &fa, nullptr, argv.data(), environ) != 0)
            die(fmt::format("cannot start {}", args[0]));
        posix_spawn_file_actions_destroy(&fa);
        ::close(fds[1]);
        out_ = fds[0];
    }
    ~Watched() {
        ::kill(pid_, SIGINT);
        int status = 0;
        ::waitpid(pid_, &status, 0);
        ::close(out_);
        ::close(notify_);
    }
    Clock::time_point started() const { return started_; }

    /** Waits until a new image (EXR and PNG pair) has been written; returns when. */
    Clock::time_point wait_image(double timeout_s = 120.0) {
        const auto start = Clock::now();
        for (;;) {
            if (exr_ > 0 && png_ > 0) {
                --exr_;
                --png_;
                return Clock::now();
            }
            if (seconds_since(start) > timeout_s) die("timed out waiting for an image:\n" + lines_);
            pollfd p[2] = {{notify_, POLLIN, 0}, {out_, POLLIN, 0}};
            ::poll(p, 2, 100);
            if (p[1].revents & POLLIN) read_lines();
            if (p[1].revents & POLLHUP) die("spangle exited:\n" + lines_);
            alignas(inotify_event) char buf[4096];
            const ssize_t n = ::read(notify_, buf, sizeof(buf));
            for (ssize_t off = 0; off < n;) {
                inotify_event ev;
                std::memcpy(&ev, buf + off, sizeof(ev));
                const std::string name(buf + off + sizeof(inotify_event));
                off += static_cast<ssize_t>(sizeof(inotify_event) + ev.len);
                exr_ += name == "out.exr";
                png_ += name == "out.png";
            }
        }
    }
    /** Waits for the first image of a new render: its preview pass, or its first full pass
     *  when the film is too small for a preview (an image whose EXR says 0 or 1 spp: the render
     *  an edit interrupted may still write a later pass first). Returns when the first image
     *  and the first full pass were written. */
    std::pair<Clock::time_point, Clock::time_point> wait_new_render(const fs::path& exr) {
        for (;;) {
            const auto at = wait_image();
            auto in = OIIO::ImageInput::open(exr.string());
            const std::string spp = in ? in->spec().get_string_attribute("spangle:spp") : "";
            if (spp == "0") return {at, wait_image()};
            if (spp == "1") return {at, at};
        }
    }
    /** Waits for a stdout line matching `re`; returns it. */
    std::string wait_line(const std::regex& re, double timeout_s = 300.0) {
        const auto start = Clock::now();
        for (;;) {
            std::size_t nl;
            while ((nl = lines_.find('\n', seen_)) != std::string::npos) {
                const std::string line = lines_.substr(seen_, nl - seen_);
                seen_ = nl + 1;
                if (std::regex_search(line, re)) return line;
            }
            if (seconds_since(start) > timeout_s) die("timed out waiting for output:\n" + lines_);
            pollfd p{out_, POLLIN, 0};
            ::poll(&p, 1, 100);
            if (p.revents & POLLIN) read_lines();
            if (p.revents & POLLHUP) die("spangle exited:\n" + lines_);
        }
    }
    /** Resident and peak memory of the process, in MiB. */
    std::pair<double, double> memory() const {
        std::ifstream in(fmt::format("/proc/{}/status", pid_));
        std::string key;
        double rss = 0, hwm = 0, kb = 0;
        while (in >> key) {
            if (key == "VmRSS:" && in >> kb) rss = kb / 1024.0;
            if (key == "VmHWM:" && in >> kb) hwm = kb / 1024.0;
        }
        return {rss, hwm};
    }

private:
    void read_lines() {
        char buf[4096];
        const ssize_t n = ::read(out_, buf, sizeof(buf));
        if (n > 0) lines_.append(buf, static_cast<std::size_t>(n));
    }
    pid_t pid_ = -1;
    int out_ = -1, notify_ = -1;
    int exr_ = 0, png_ = 0;  // renamed into place, not yet paired
    std::string lines_;
    std::size_t seen_ = 0;
    Clock::time_point started_;
};

/** The text of the first `[[kind]]` block (from its header to the next header). */
std::pair<std::size_t, std::size_t> block_of(const std::string& text, const std::string& kind,
                                             const std::string& must_contain = "") {
    std::size_t at = 0;
    while ((at = text.find("[[" + kind + "]]", at)) != std::string::npos) {
        std::size_t end = text.find("\n[", at + 2);
        if (end == std::string::npos) end = text.size();
        if (must_contain.empty() ||
            text.substr(at, end - at).find(must_contain) != std::string::npos)
            return {at, end};
        at = end;
    }
    return {std::string::npos, std::string::npos};
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v.empty() ? 0.0 : v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
    const fs::path self = fs::canonical("/proc/self/exe").parent_path();
    std::string scene, spangle = (self / "spangle").string(), plugins = (self / "plugins").string();
    std::string threads, size;
    int repeats = 5, reloads = 100;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto next = [&]() -> std::string {
            if (i + 1 >= argc) die(a + " needs a value");
            return argv[++i];
        };
        if (a == "--spangle")
            spangle = next();
        else if (a == "--plugin-path")
            plugins = next();
        else if (a == "--threads")
            threads = next();
        else if (a == "--size")
            size = next();
        else if (a == "--repeats")
            repeats = std::stoi(next());
        else if (a == "--reloads")
            reloads = std::stoi(next());
        else if (!a.empty() && a[0] != '-' && scene.empty())
            scene = a;
        else
            die("usage: spangle_reload_bench SCENE [--spangle PATH] [--plugin-path DIR] "
                "[--threads N] [--size WxH] [--repeats N] [--reloads N]");
    }
    if (scene.empty()) die("no scene given");
    // A copy of the folder above the scene's (scenes refer to ../meshes, ../env).
    const fs::path scene_abs = fs::canonical(scene);
    const fs::path root = scene_abs.parent_path().parent_path();
    const fs::path tmp = fs::temp_directory_path() / fmt::format("spangle-reload-{}", ::getpid());
    fs::create_directories(tmp);
    fs::copy(root, tmp / "tree", fs::copy_options::recursive);
    const fs::path copy = tmp / "tree" / fs::relative(scene_abs, root);
    const fs::path out_dir = tmp / "out";
    fs::create_directories(out_dir);
    const fs::path exr = out_dir / "out.exr";

    std::string text = read_file(copy);
    const std::string original = text;
    // The object the transform and cage edits touch.
    auto [ob, oe] = block_of(text, "object", "subdiv");
    if (ob == std::string::npos) std::tie(ob, oe) = block_of(text, "object");
    if (ob == std::string::npos) die("the scene has no object");
    std::smatch m;
    const std::string object_block = text.substr(ob, oe - ob);
    const std::regex mesh_re("mesh\\s*=\\s*\"([^\"]+)\"");
    if (!std::regex_search(object_block, m, mesh_re)) die("the object has no mesh");
    const fs::path cage = copy.parent_path() / m[1].str();
    const bool subdivided = object_block.find("subdiv") != std::string::npos;

    int edit_count = 0;
    auto edit_material = [&] {
        ++edit_count;
        auto [b, e] = block_of(text, "material");
        if (b == std::string::npos) die("the scene has no material");
        const std::size_t params = text.find("params", b);
        const std::regex num("[0-9]+\\.?[0-9]*");
        std::smatch n;
        const std::string tail = text.substr(params, e - params);
        if (params >= e || !std::regex_search(tail, n, num)) die("no numeric material parameter");
        const double v = std::stod(n.str()) * (1.0 + 0.001 * (edit_count % 50 + 1));
        text.replace(params + static_cast<std::size_t>(n.position()),
                     static_cast<std::size_t>(n.length()), fmt::format("{:.6g}", v));
        save(copy, text);
    };
    auto edit_transform = [&] {
        ++edit_count;
        auto [b, e] = block_of(text, "object", subdivided ? "subdiv" : "");
        const std::string line =
            fmt::format("translate = [{:.4f}, 0, 0]  # bench\n", 0.002 * (edit_count % 50 + 1));
        const std::size_t at = text.find("translate = [", b);
        if (at != std::string::npos && at < e && text.find("# bench", at) < e)
            text.replace(at, text.find('\n', at) + 1 - at, line);
        else
            text.insert(text.find('\n', b) + 1, line);
        save(copy, text);
    };
    auto edit_cage = [&] {
        ++edit_count;
        save(cage, read_file(cage) + fmt::format("# bench edit {}\n", edit_count));
    };

    std::vector<std::string> args = {spangle,         "render", copy.string(),
                                     "--watch",       "-o",     (out_dir / "out.exr").string(),
                                     "--plugin-path", plugins};
    if (!size.empty()) {
        args.push_back("--size");
        args.push_back(size);
    }
    if (!threads.empty()) {
        args.push_back("--threads");
        args.push_back(threads);
    }
    fmt::print("scene: {}\nspangle: {}\n", scene, spangle);
    std::fflush(stdout);

    // Cold starts: a fresh process each time, to the first picture and the first full pass.
    std::vector<double> cold_preview, cold_full;
    for (int r = 0; r < std::max(1, repeats / 2); ++r) {
        Watched w(args, out_dir);
        const auto [preview, full] = w.wait_new_render(exr);
        cold_preview.push_back(std::chrono::duration<double>(preview - w.started()).count());
        cold_full.push_back(std::chrono::duration<double>(full - w.started()).count());
    }
    const double cold = median(cold_preview);
    fmt::print("cold start (process start to image written), median of {}:\n", cold_preview.size());
    fmt::print("  first picture (preview pass)   {:8.3f} s\n", cold);
    fmt::print("  first full pass (1 spp)        {:8.3f} s\n\n", median(cold_full));

    Watched w(args, out_dir);
    w.wait_new_render(exr);
    const std::regex reload_re("^reload");
    fmt::print("{:<10} {:>14} {:>10} {:>16}   what the reload line says (last repeat)\n", "edit",
               "first picture", "of cold", "first full pass");
    struct Kind {
        const char* name;
        std::function<void()> edit;
    };
    std::vector<Kind> kinds = {{"material", edit_material}, {"transform", edit_transform}};
    if (subdivided) kinds.push_back({"cage", edit_cage});
    for (const Kind& k : kinds) {
        std::vector<double> first, full;
        std::string line;
        for (int r = 0; r < repeats; ++r) {
            const auto t0 = Clock::now();
            k.edit();
            const auto [preview, pass] = w.wait_new_render(exr);
            line = w.wait_line(reload_re);
            first.push_back(std::chrono::duration<double>(preview - t0).count());
            full.push_back(std::chrono::duration<double>(pass - t0).count());
        }
        const auto semi = line.find("; ran:");
        const auto end = line.find("; applied");
        fmt::print("{:<10} {:>12.3f} s {:>9.1f}% {:>14.3f} s   {}\n", k.name, median(first),
                   100.0 * median(first) / cold, median(full),
                   semi != std::string::npos && end != std::string::npos
                       ? line.substr(semi + 2, end - semi - 2)
                       : line);
        std::fflush(stdout);
    }

    // Memory over many reloads: material edits, each saved once the previous one has written its
    // first full pass (the render it interrupts has built everything it builds).
    fmt::print("\nmemory over {} material reloads (resident MiB):\n", reloads);
    fmt::print("  {:>5} reloads: {:8.1f}\n", 0, w.memory().first);
    for (int r = 1; r <= reloads; ++r) {
        edit_material();
        w.wait_new_render(exr);
        if (r == 1 || r == 10 || r == 25 || r == 50 || r == reloads || r % 100 == 0)
            fmt::print("  {:>5} reloads: {:8.1f}\n", r, w.memory().first);
        std::fflush(stdout);
    }
    fmt::print("  peak resident: {:.1f} MiB\n", w.memory().second);
    save(copy, original);
    std::error_code ec;
    fs::remove_all(tmp, ec);
    return 0;
}
