// A serial OpenMP runtime: the three entry points CHOLMOD's supernodal factorization calls
// (GOMP_parallel, omp_get_num_threads, omp_get_thread_num), running every parallel region on the
// calling thread as a team of one, which is what OpenMP itself does with one thread.
//
// Why: CHOLMOD 5.12 opens a parallel region for every supernode (with a fixed thread count of
// its own, whatever OMP_NUM_THREADS says). Through libgomp each region costs thread hand-offs
// or, with a single thread, a futex system call: on smallGrid3D 1,321 regions per solve, 2,100
// context switches with threads; 25 ms instead of 32 ms per whole `moslam solve` without them
// (README, the solve table). Our systems are too small for the parallel copy loops to pay.
//
// Linked as an object library into the executables that use CHOLMOD and want no OpenMP threads
// (moslam, moslam-robot, the tests, the benchmarks): their definitions take precedence over
// libgomp's, so libgomp need not be loaded at all. An executable whose other libraries use
// OpenMP for real (moslam-perception: PCL) links libgomp instead (OpenMP::OpenMP_CXX).
extern "C" {

void GOMP_parallel(void (*fn)(void*), void* data, unsigned /*num_threads*/, unsigned /*flags*/) {
  fn(data);
}

int omp_get_num_threads() { return 1; }

int omp_get_thread_num() { return 0; }

}  // extern "C"
