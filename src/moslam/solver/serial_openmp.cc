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
// Linked as an object library into every executable (moslam, moslam-robot, moslam-perception,
// the tests, the benchmarks): their definitions take precedence over libgomp's, so libgomp need
// not be loaded at all where only CHOLMOD uses it. moslam-perception loads libgomp for PCL, whose
// other OpenMP entry points (worksharing, barriers) handle a region run this way as a team of
// one. There the reason is FLANN, which opens a region of one thread (SearchParams::cores = 1)
// around every k-d tree query PCL makes: through libgomp each costs a futex call and an
// allocation, and GICP ran 4-6x slower (README, the perception table). Nothing moslam calls in
// PCL asks for more than one thread (PCL's *OMP classes do; moslam uses none of them).
extern "C" {

void GOMP_parallel(void (*fn)(void*), void* data, unsigned /*num_threads*/, unsigned /*flags*/) {
  fn(data);
}

int omp_get_num_threads() { return 1; }

int omp_get_thread_num() { return 0; }

}  // extern "C"
