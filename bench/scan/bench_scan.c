/* Virtual scanner throughput on one core: scene build (growth + BVH) and
 * scans of single trees and a plot with each scanner kind, reporting pulses,
 * points and points per second. Usage: bench_scan [threads] (default 1). */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "stages/core/parallel.h"
#include "stages/core/progress.h"
#include "stages/scan/scan.h"

static int run(const char *label, const char *species, double plot, sy_scanner_kind kind, double step,
               double density, int subrays)
{
    sy_scene_options o;
    o = sy_scene_options_default();
    o.species[0] = species;
    o.n_species = 1;
    if (plot > 0) {
        o.species[1] = "black_oak";
        o.species[2] = "european_pine";
        o.n_species = 3;
        o.plot_size = plot;
        o.trees = 5;
    }
    sy_error err = {0};
    sy_scene s;
    double t0 = sy_now();
    if (sy_scene_build(&s, &o, 0, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    double t_build = sy_now() - t0;
    sy_scan_options sc;
    sc = sy_scan_options_for(kind);
    if (step > 0) sc.step_deg = step;
    if (density > 0) sc.density = density;
    sc.subrays = subrays;
    sc.lawnmower = plot > 0;
    sy_cloud c;
    sy_scan_stats st;
    clock_t cpu0 = clock();
    if (sy_scan(&s, &sc, &c, &st, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        sy_scene_free(&s);
        return 1;
    }
    /* CPU time too: on a shared machine wall time includes other work. */
    double cpu = (double)(clock() - cpu0) / CLOCKS_PER_SEC;
    printf("%-30s prims %7zu  build %5.2f s  pulses %8zu  points %8zu  scan %6.2f s (cpu %6.2f s)  %5.2f Mpts/cpu-s"
           "  %5.2f Mpulses/cpu-s\n",
           label, s.prims.n, t_build, st.pulses, st.points, st.seconds, cpu, st.points / cpu * 1e-6,
           st.pulses / cpu * 1e-6);
    sy_cloud_free(&c);
    sy_scene_free(&s);
    return 0;
}

int main(int argc, char **argv)
{
    sy_set_threads(argc > 1 ? atoi(argv[1]) : 1);
    sy_progress_set_quiet(1);
    printf("threads: %d\n", sy_threads());
    int bad = 0;
    bad |= run("aspen TLS 0.06 deg, 5 rays", "quaking_aspen", 0, SY_SCANNER_TERRESTRIAL, 0.06, 0, 5);
    bad |= run("aspen TLS 0.06 deg, 1 ray", "quaking_aspen", 0, SY_SCANNER_TERRESTRIAL, 0.06, 0, 1);
    bad |= run("oak TLS 0.1 deg, 5 rays", "black_oak", 0, SY_SCANNER_TERRESTRIAL, 0.1, 0, 5);
    bad |= run("aspen MLS 0.25 deg, 5 rays", "quaking_aspen", 0, SY_SCANNER_MOBILE, 0, 0, 5);
    bad |= run("aspen ALS 200/m2, 5 rays", "quaking_aspen", 0, SY_SCANNER_AIRBORNE, 0, 200, 5);
    bad |= run("plot 30 m TLS 0.1 deg, 5 rays", "quaking_aspen", 30, SY_SCANNER_TERRESTRIAL, 0.1, 0, 5);
    return bad;
}
