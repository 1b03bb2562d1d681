#pragma once
// Rendering one image over the ranks of an MPI job (`mpirun -np N spangle render ...`). Every
// rank loads the scene through its own Session (BVHs, subdivision and plugins built once per
// rank); the image is cut into bands of whole tile rows and handed out on request: a rank asks
// rank 0 for the next band when it has finished its last one, so ranks that drew sky bands take
// more of them than ranks that drew glitter. Rank 0 renders bands too (a thread of it answers the
// others) and places every band in the image, which is the one-process image bit for bit: a
// pixel's samples depend on the pixel alone, whichever rank traces it.
//
// Only mpi_render.cpp sees <mpi.h>; the build has it (and mpi_command.cpp, the render mode that
// drives it) when SPANGLE_MPI is on and MPI was found (SPANGLE_HAVE_MPI). What the launcher says
// before MPI starts is read in every build (launcher.h).

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "render/render_options.h"

namespace spangle {

class Session;

/** One rank's share of a distributed render. */
struct RankLoad {
    uint32_t units = 0;    ///< bands it rendered
    double busy = 0.0;     ///< seconds it spent rendering them
    uint64_t samples = 0;  ///< camera samples it traced
};

/** The whole image of a distributed render, on rank 0 (empty elsewhere). */
struct DistributedImage {
    uint32_t width = 0, height = 0;        ///< of the crop window (the whole image without one)
    ImageWindow window;                    ///< where the window lies in the full frame
    std::vector<float> image;              ///< RGB, working space
    std::vector<float> layers;             ///< with --layers
    std::vector<std::string> layer_names;  ///< the layers' EXR channel names
    RenderStats stats;                     ///< counters summed over the ranks; seconds: wall time
    std::vector<RankLoad> loads;           ///< per rank
    uint32_t units = 0;                    ///< bands the image was cut into

    /** Busiest rank's time over the mean (1 = perfect balance). */
    double balance() const;
};

/** The MPI job this process is part of: started by the constructor (threads: serialized; rank 0
 *  answers requests on a second thread), finished by the destructor. */
class MpiJob {
public:
    /** Starts MPI (MPI_Init_thread may take its own arguments out of argc and argv); throws
     *  SpangleError when it cannot, or cannot be called from a second thread. */
    MpiJob(int& argc, char**& argv);
    ~MpiJob();
    MpiJob(const MpiJob&) = delete;
    MpiJob& operator=(const MpiJob&) = delete;

    /** This process's rank in MPI_COMM_WORLD. */
    int rank() const { return rank_; }
    /** Ranks in the job. */
    int size() const { return size_; }
    /** The machine this rank runs on, as MPI names it. */
    const std::string& host() const { return host_; }
    /** "rank R of N on HOST", for messages. */
    std::string who() const;

    /** Collective: every rank says whether its step succeeded; returns the ranks that failed
     *  (empty when all succeeded). */
    std::vector<int> failed_ranks(bool ok) const;
    /** Ends every rank of the job (after this rank has printed why). */
    [[noreturn]] void abort(int code) const;

    /** Collective: renders the session's live scene (loaded on every rank, the same file and
     *  options) over all ranks. `crop`: the window to render (whole() for the image);
     *  `band_rows`: tile rows per unit of work. `progress` (rank 0; may be empty) gets (samples
     *  done, samples total) as bands arrive. The image lands in `out` on rank 0. Returns false
     *  on every rank when a check before the first band failed on any (the first failing rank
     *  printed why); a rank failing later ends the job. */
    bool render(Session& session, const CropWindow& crop, uint32_t band_rows,
                const std::function<void(uint64_t, uint64_t)>& progress,
                DistributedImage& out) const;

private:
    int rank_ = 0, size_ = 1;  ///< this rank and the job's size
    std::string host_;         ///< MPI_Get_processor_name
};

}  // namespace spangle
