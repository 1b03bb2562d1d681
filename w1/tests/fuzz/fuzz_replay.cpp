// Replays fuzz inputs through the same targets without libFuzzer (any compiler):
//   spangle_fuzz_replay TARGET FILE_OR_FOLDER...
// Prints one line per target with how many inputs were accepted and refused. A crash, a sanitizer
// report or an exception other than SpangleError ends it with the input's name on stderr.
#include <cstdint>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <vector>

#include "fuzz_targets.h"

namespace fs = std::filesystem;

int main(int argc, char** argv) {
    if (argc < 3) {
        std::cerr << "usage: spangle_fuzz_replay TARGET FILE_OR_FOLDER...\n";
        return 2;
    }
    const std::string target = argv[1];
    std::vector<fs::path> inputs;
    for (int i = 2; i < argc; ++i) {
        const fs::path p = argv[i];
        if (fs::is_directory(p)) {
            for (const auto& e : fs::directory_iterator(p))
                if (e.is_regular_file()) inputs.push_back(e.path());
        } else {
            inputs.push_back(p);
        }
    }
    std::size_t accepted = 0;
    std::size_t refused = 0;
    for (const fs::path& p : inputs) {
        std::ifstream in(p, std::ios::binary);
        const std::vector<char> bytes{std::istreambuf_iterator<char>(in), {}};
        try {
            if (spangle::fuzz::run_one(target, reinterpret_cast<const std::uint8_t*>(bytes.data()),
                                       bytes.size()))
                ++accepted;
            else
                ++refused;
        } catch (const std::exception& e) {
            std::cerr << p.string() << ": escaped the loader: " << e.what() << "\n";
            return 1;
        }
    }
    std::cout << target << ": " << inputs.size() << " inputs, " << accepted << " accepted, "
              << refused << " refused with a message\n";
    return inputs.empty() ? 1 : 0;
}
