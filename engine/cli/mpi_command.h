#pragma once
// `mpirun -np N spangle render ...`: a still or --frames rendered by the ranks together (built
// only with MPI: SPANGLE_HAVE_MPI).

#include "cli/render_args.h"

namespace spangle {

/** Starts MPI (from main's argc and argv) and renders as one rank of the job: every rank loads
 *  the scene; the image (or each frame of --frames) is cut into bands handed out on request;
 *  rank 0 writes it. A step that fails on any rank ends every rank, the first that failed saying
 *  why. Returns the exit status; throws UsageError or SpangleError (MPI could not start). */
int run_render_mpi(const RenderArgs& a, int& argc, char**& argv);

}  // namespace spangle
