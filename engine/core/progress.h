#pragma once
// Progress of long work before a render starts: reading mesh files, subdividing cages, building
// BVHs. A level-8 subdivision or a BVH over millions of triangles takes minutes; the command line
// shows how far it is (cli/progress.h) as it shows a render's samples.

#include <functional>
#include <string>

namespace spangle {

/** Told how far one piece of work is: `what` names it ("subdividing body.obj at level 8"),
 *  `fraction` in [0, 1] how much of it is done, 1 on the last call for that piece. Called on the
 *  thread doing the work, never concurrently; may be empty (nobody listens). */
using WorkProgress = std::function<void(const std::string& what, double fraction)>;

}  // namespace spangle
