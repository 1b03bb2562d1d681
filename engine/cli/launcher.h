#pragma once
// What an MPI launcher (mpirun, srun) tells a process through its environment before MPI is
// started. Read in every build, with or without MPI: a spangle built without it still has to
// know that it was started as one of several ranks (and refuse to render the whole image in
// each), and only rank 0 reports a bad command line.

namespace spangle {

/** The job's size and this process's rank, as the launcher set them (1 and 0 outside one). */
struct LauncherInfo {
    int size = 1;        ///< ranks in the job
    int rank = 0;        ///< this process's rank
    int local_size = 1;  ///< ranks on this machine
};

/** Reads Open MPI's variables, then MPICH/Hydra's (not Slurm's SLURM_NTASKS: a batch script
 *  has it without being a rank). */
LauncherInfo launcher_info();

}  // namespace spangle
