/* The COLMAP driver (see photogrammetry.h). COLMAP runs as a subprocess,
 * its stdout and stderr appended to one log in the workspace; while a step
 * runs the driver polls it and reports elapsed time. Structure from motion
 * recovers the scene only up to a similarity, so after mapping the model is
 * rotated to put the cameras' mean up vector on +Z (photos are taken mostly
 * level, so their up vectors scatter around the true vertical) and scaled
 * by the user's reference. */
#include "photogrammetry.h"

#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "../ingest/ingest.h"

enum { N_STEPS_SPARSE = 3, N_STEPS_DENSE = 6 };

sy_photogrammetry_options sy_photogrammetry_options_default(void)
{
    sy_photogrammetry_options o;
    memset(&o, 0, sizeof o);
    o.colmap = "colmap";
    o.quality = SY_PHOTO_MEDIUM;
    o.min_registered = 0.5;
    return o;
}

sy_code sy_photogrammetry_options_check(const sy_photogrammetry_options *o, sy_error *err)
{
    if (!o->colmap || !o->colmap[0]) return sy_fail(err, SY_EUSAGE, "photogrammetry: colmap executable is empty");
    if (!o->workspace || !o->workspace[0]) return sy_fail(err, SY_EUSAGE, "photogrammetry: workspace is required");
    if (strlen(o->workspace) > 3800) return sy_fail(err, SY_EUSAGE, "photogrammetry: workspace path too long");
    if (o->quality < SY_PHOTO_LOW || o->quality > SY_PHOTO_HIGH)
        return sy_fail(err, SY_EUSAGE, "photogrammetry: quality must be low, medium or high");
    if (o->threads < 0) return sy_fail(err, SY_EUSAGE, "photogrammetry: threads must be >= 0");
    if (o->sequential_overlap < 0 || o->sequential_overlap > 1000)
        return sy_fail(err, SY_EUSAGE, "photogrammetry: sequential_overlap must be in 0..1000");
    if (!(o->min_registered > 0 && o->min_registered <= 1))
        return sy_fail(err, SY_EUSAGE, "photogrammetry: min_registered must be in (0, 1], got %g", o->min_registered);
    int ref = o->scale_image_a || o->scale_image_b || o->scale_distance != 0;
    if (ref && (!o->scale_image_a || !o->scale_image_b || !(o->scale_distance > 0) || !isfinite(o->scale_distance)))
        return sy_fail(err, SY_EUSAGE, "photogrammetry: a scale reference needs two image names and a distance > 0");
    if (o->camera_spacing != 0 && !(o->camera_spacing > 0 && isfinite(o->camera_spacing)))
        return sy_fail(err, SY_EUSAGE, "photogrammetry: camera_spacing must be > 0, got %g", o->camera_spacing);
    if (ref && o->camera_spacing != 0)
        return sy_fail(err, SY_EUSAGE, "photogrammetry: give a scale reference or a camera spacing, not both");
    return SY_OK;
}

static int is_image_name(const char *name)
{
    static const char *exts[] = {"jpg", "jpeg", "png", "tif", "tiff", "bmp", "ppm", "pgm"};
    const char *dot = strrchr(name, '.');
    if (!dot || name[0] == '.') return 0;
    char ext[8] = {0};
    size_t n = strlen(dot + 1);
    if (n == 0 || n >= sizeof ext) return 0;
    for (size_t i = 0; i < n && i < sizeof ext - 1; i++) ext[i] = (char)tolower((unsigned char)dot[1 + i]);
    for (size_t i = 0; i < sizeof exts / sizeof exts[0]; i++)
        if (strcmp(ext, exts[i]) == 0) return 1;
    return 0;
}

size_t sy_photogrammetry_count_images(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d) return 0;
    size_t n = 0;
    for (struct dirent *e; (e = readdir(d));) n += is_image_name(e->d_name);
    closedir(d);
    return n;
}

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Runs argv (argv[0] looked up on PATH) with stdout and stderr appended to
 * log; reports elapsed time about every second. Returns the exit status,
 * 127 when it could not start, 128 + signal when killed. */
static int run_logged(char *const argv[], const char *log, const sy_photogrammetry_options *o, const char *step,
                      int index, int steps)
{
    FILE *lf = fopen(log, "a");
    if (lf) {
        fprintf(lf, "\n==== sylva photogrammetry: %s:", step);
        for (int i = 0; argv[i]; i++) fprintf(lf, " %s", argv[i]);
        fprintf(lf, "\n");
        fclose(lf);
    }
    pid_t pid = fork();
    if (pid < 0) return 127;
    if (pid == 0) {
        int fd = open(log, O_WRONLY | O_APPEND | O_CREAT, 0644);
        int null = open("/dev/null", O_RDONLY);
        if (fd >= 0) {
            dup2(fd, 1);
            dup2(fd, 2);
        }
        if (null >= 0) dup2(null, 0);
        /* COLMAP's Qt parts must not look for a display */
        setenv("QT_QPA_PLATFORM", "offscreen", 1);
        execvp(argv[0], argv);
        _exit(127);
    }
    double t0 = now(), last = t0;
    if (o->progress) o->progress(o->progress_user, step, index, steps, 0.0);
    for (;;) {
        int status;
        pid_t r = waitpid(pid, &status, WNOHANG);
        if (r == pid) {
            if (o->progress) o->progress(o->progress_user, step, index, steps, now() - t0);
            if (WIFEXITED(status)) return WEXITSTATUS(status);
            if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
            return 1;
        }
        if (r < 0 && errno != EINTR) return 127;
        struct timespec nap = {0, 100 * 1000 * 1000};
        nanosleep(&nap, NULL);
        double t = now();
        if (t - last >= 1.0) {
            last = t;
            if (o->progress) o->progress(o->progress_user, step, index, steps, t - t0);
        }
    }
}

/* Whether `colmap -h` says it was built with CUDA (dense stereo needs it). */
static int colmap_has_cuda(const char *colmap)
{
    char cmd[4200];
    snprintf(cmd, sizeof cmd, "QT_QPA_PLATFORM=offscreen '%s' -h 2>&1", colmap);
    FILE *p = popen(cmd, "r");
    if (!p) return 0;
    char line[512];
    int cuda = 0;
    for (int i = 0; i < 5 && fgets(line, sizeof line, p); i++)
        if (strstr(line, "with CUDA") && !strstr(line, "without CUDA")) cuda = 1;
    while (fgets(line, sizeof line, p)) {
    }
    pclose(p);
    return cuda;
}

/* Whether the log holds text (for explaining failures in COLMAP's words). */
static int log_mentions(const char *log, const char *text)
{
    sy_buffer b;
    sy_error e;
    if (sy_read_file(log, &b, &e)) return 0;
    int found = strstr((const char *)b.data, text) != NULL;
    sy_buffer_free(&b);
    return found;
}

static void quat_to_matrix(const double q[4], double R[3][3])
{
    double w = q[0], x = q[1], y = q[2], z = q[3], n = sqrt(w * w + x * x + y * y + z * z);
    if (n > 0) w /= n, x /= n, y /= n, z /= n;
    R[0][0] = 1 - 2 * (y * y + z * z), R[0][1] = 2 * (x * y - w * z), R[0][2] = 2 * (x * z + w * y);
    R[1][0] = 2 * (x * y + w * z), R[1][1] = 1 - 2 * (x * x + z * z), R[1][2] = 2 * (y * z - w * x);
    R[2][0] = 2 * (x * z - w * y), R[2][1] = 2 * (y * z + w * x), R[2][2] = 1 - 2 * (x * x + y * y);
}

/* The rotation taking unit vector u onto +Z (Rodrigues). */
static void rotation_to_z(const double u[3], double M[3][3])
{
    double c = u[2], ax[3] = {u[1], -u[0], 0}, s = sqrt(ax[0] * ax[0] + ax[1] * ax[1]);
    memset(M, 0, 9 * sizeof(double));
    if (s < 1e-12) {
        M[0][0] = 1, M[1][1] = c >= 0 ? 1 : -1, M[2][2] = c >= 0 ? 1 : -1;
        return;
    }
    ax[0] /= s, ax[1] /= s;
    double K[3][3] = {{0, -ax[2], ax[1]}, {ax[2], 0, -ax[0]}, {-ax[1], ax[0], 0}};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double kk = 0;
            for (int k = 0; k < 3; k++) kk += K[i][k] * K[k][j];
            M[i][j] = (i == j) + s * K[i][j] + (1 - c) * kk;
        }
}

static int cmp_pose_name(const void *a, const void *b)
{
    return strcmp(((const sy_colmap_pose *)a)->name, ((const sy_colmap_pose *)b)->name);
}

/* The sparse model with the most registered images among sparse/0, 1, ... */
static sy_code pick_model(const char *ws, char *dir, size_t cap, sy_colmap_pose **poses, size_t *n, sy_error *err)
{
    *poses = NULL;
    *n = 0;
    for (int k = 0; k < 64; k++) {
        char d[4096];
        if (snprintf(d, sizeof d, "%s/sparse/%d", ws, k) >= (int)sizeof d) break;
        struct stat st;
        if (stat(d, &st) != 0) break;
        sy_colmap_pose *p;
        size_t m;
        sy_error e;
        if (sy_read_colmap_poses(d, &p, &m, &e) != SY_OK) continue;
        if (m > *n) {
            free(*poses);
            *poses = p;
            *n = m;
            snprintf(dir, cap, "%.4000s", d);
        } else {
            free(p);
        }
    }
    (void)err;
    return SY_OK;
}

void sy_photogrammetry_result_free(sy_photogrammetry_result *r)
{
    sy_cloud_free(&r->cloud);
    free(r->camera_names);
    free(r->camera_centres);
    r->camera_names = NULL;
    r->camera_centres = NULL;
}

static sy_code make_dir(const char *path, sy_error *err)
{
    if (mkdir(path, 0755) == 0 || errno == EEXIST) return SY_OK;
    return sy_fail(err, SY_EINPUT, "%s: cannot create folder: %s", path, strerror(errno));
}

static sy_code colmap_step(char *const argv[], const char *log, const sy_photogrammetry_options *o, const char *step,
                           int index, int steps, sy_error *err)
{
    int rc = run_logged(argv, log, o, step, index, steps);
    if (rc == 127)
        return sy_fail(err, SY_EINTERNAL, "photogrammetry: cannot run '%s' (install COLMAP: apt-get install colmap)",
                       o->colmap);
    if (rc) return sy_fail(err, SY_EINTERNAL, "photogrammetry: colmap %s failed (status %d); see %s", argv[1], rc, log);
    return SY_OK;
}

/* Brings the model into Sylva's frame: rotation R (mean camera up -> +Z)
 * and scale s, applied to points and cameras. */
static sy_code to_sylva_frame(const char *images_dir, const sy_photogrammetry_options *o, sy_colmap_pose *poses,
                              size_t n, sy_photogrammetry_result *out, sy_error *err)
{
    qsort(poses, n, sizeof *poses, cmp_pose_name);
    double *centre = calloc(3 * n, sizeof(double));
    out->camera_names = calloc(n, sizeof *out->camera_names);
    if (!centre || !out->camera_names) {
        free(centre);
        return sy_fail(err, SY_EINTERNAL, "photogrammetry: out of memory");
    }
    double up[3] = {0, 0, 0}, ups[3 * 64];
    for (size_t i = 0; i < n; i++) {
        double R[3][3];
        quat_to_matrix(poses[i].q, R);
        for (int k = 0; k < 3; k++)
            centre[3 * i + k] = -(R[0][k] * poses[i].t[0] + R[1][k] * poses[i].t[1] + R[2][k] * poses[i].t[2]);
        for (int k = 0; k < 3; k++) {
            up[k] -= R[1][k]; /* image y points down */
            if (i < 64) ups[3 * i + k] = -R[1][k];
        }
        memcpy(out->camera_names[i], poses[i].name, sizeof out->camera_names[i]);
    }
    double len = sqrt(up[0] * up[0] + up[1] * up[1] + up[2] * up[2]);
    if (!(len > 1e-9)) {
        free(centre);
        return sy_fail(err, SY_EINPUT, "%s: the cameras' up vectors cancel out; no up axis to level the model",
                       images_dir);
    }
    for (int k = 0; k < 3; k++) up[k] /= len;
    double spread = 0;
    size_t m = n < 64 ? n : 64;
    for (size_t i = 0; i < m; i++)
        spread += acos(fmax(-1, fmin(1, ups[3 * i] * up[0] + ups[3 * i + 1] * up[1] + ups[3 * i + 2] * up[2])));
    out->up_spread_deg = m ? spread / (double)m * 180 / 3.14159265358979323846 : 0;
    double M[3][3];
    rotation_to_z(up, M);
    /* scale */
    double s = 1;
    out->scaled = 0;
    if (o->scale_image_a) {
        long ia = -1, ib = -1;
        for (size_t i = 0; i < n; i++) {
            if (strcmp(poses[i].name, o->scale_image_a) == 0) ia = (long)i;
            if (strcmp(poses[i].name, o->scale_image_b) == 0) ib = (long)i;
        }
        if (ia < 0 || ib < 0) {
            free(centre);
            return sy_fail(err, SY_EINPUT, "%s: scale reference image '%s' did not register (or is not in the folder)",
                           images_dir, ia < 0 ? o->scale_image_a : o->scale_image_b);
        }
        double d = 0;
        for (int k = 0; k < 3; k++) d += pow(centre[3 * ia + k] - centre[3 * ib + k], 2);
        if (!(sqrt(d) > 1e-12)) {
            free(centre);
            return sy_fail(err, SY_EINPUT, "%s: scale reference images '%s' and '%s' were taken from the same place",
                           images_dir, o->scale_image_a, o->scale_image_b);
        }
        s = o->scale_distance / sqrt(d);
        out->scaled = 1;
    } else if (o->camera_spacing > 0) {
        double sum = 0;
        for (size_t i = 1; i < n; i++) {
            double d = 0;
            for (int k = 0; k < 3; k++) d += pow(centre[3 * i + k] - centre[3 * (i - 1) + k], 2);
            sum += sqrt(d);
        }
        if (n < 2 || !(sum > 1e-12)) {
            free(centre);
            return sy_fail(err, SY_EINPUT, "%s: camera spacing needs two registered cameras apart", images_dir);
        }
        s = o->camera_spacing / (sum / (double)(n - 1));
        out->scaled = 1;
    }
    out->scale = s;
    /* points: world = s * M * p, rebased on a metre-floored origin */
    sy_cloud *c = &out->cloud;
    double *world = malloc(3 * c->n * sizeof(double));
    if (!world) {
        free(centre);
        return sy_fail(err, SY_EINTERNAL, "photogrammetry: out of memory");
    }
    double lo[3] = {INFINITY, INFINITY, INFINITY};
    for (size_t i = 0; i < c->n; i++) {
        double p[3];
        for (int k = 0; k < 3; k++) p[k] = c->origin[k] + (double)c->xyz[3 * i + k];
        for (int k = 0; k < 3; k++) {
            world[3 * i + k] = s * (M[k][0] * p[0] + M[k][1] * p[1] + M[k][2] * p[2]);
            lo[k] = fmin(lo[k], world[3 * i + k]);
        }
    }
    for (int k = 0; k < 3; k++) c->origin[k] = c->n ? floor(lo[k]) : 0;
    for (size_t i = 0; i < c->n; i++)
        for (int k = 0; k < 3; k++) c->xyz[3 * i + k] = (float)(world[3 * i + k] - c->origin[k]);
    free(world);
    for (size_t i = 0; i < n; i++) {
        double p[3] = {centre[3 * i], centre[3 * i + 1], centre[3 * i + 2]};
        for (int k = 0; k < 3; k++) centre[3 * i + k] = s * (M[k][0] * p[0] + M[k][1] * p[1] + M[k][2] * p[2]);
    }
    out->camera_centres = centre;
    out->n_cameras = n;
    return SY_OK;
}

sy_code sy_photogrammetry_run(const char *images_dir, const sy_photogrammetry_options *o,
                              sy_photogrammetry_result *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    sy_code rc = sy_photogrammetry_options_check(o, err);
    if (rc) return rc;
    out->n_images = sy_photogrammetry_count_images(images_dir);
    if (out->n_images < 3)
        return sy_fail(err, SY_EINPUT, "%s: %zu photos found (.jpg .png .tif ...); photogrammetry needs at least 3",
                       images_dir, out->n_images);
    const char *ws = o->workspace;
    char db[4200], sparse[4200], dense[4200];
    snprintf(db, sizeof db, "%s/database.db", ws);
    snprintf(sparse, sizeof sparse, "%s/sparse", ws);
    snprintf(dense, sizeof dense, "%s/dense", ws);
    snprintf(out->log_path, sizeof out->log_path, "%s/colmap.log", ws);
    if ((rc = make_dir(ws, err)) || (rc = make_dir(sparse, err))) return rc;
    remove(db); /* a fresh database: COLMAP would otherwise add to an old run */
    remove(out->log_path);
    static const char *sizes[3] = {"640", "1600", "3200"}, *features[3] = {"2048", "8192", "16384"};
    char threads[32];
    snprintf(threads, sizeof threads, "%d", o->threads > 0 ? o->threads : -1);
    char *colmap = (char *)o->colmap, *img = (char *)images_dir;
    int cuda = colmap_has_cuda(o->colmap);
    int steps = cuda ? N_STEPS_DENSE : N_STEPS_SPARSE;
    char *extract[] = {colmap, "feature_extractor", "--database_path", db, "--image_path", img,
                       "--ImageReader.single_camera", "1", "--ImageReader.camera_model", "SIMPLE_RADIAL",
                       "--SiftExtraction.use_gpu", "0", "--SiftExtraction.num_threads", threads,
                       "--SiftExtraction.max_image_size", (char *)sizes[o->quality],
                       "--SiftExtraction.max_num_features", (char *)features[o->quality], NULL};
    char overlap[32];
    snprintf(overlap, sizeof overlap, "%d", o->sequential_overlap);
    char *match_all[] = {colmap, "exhaustive_matcher", "--database_path", db, "--SiftMatching.use_gpu", "0",
                         "--SiftMatching.num_threads", threads, NULL};
    char *match_seq[] = {colmap, "sequential_matcher", "--database_path", db, "--SiftMatching.use_gpu", "0",
                         "--SiftMatching.num_threads", threads, "--SequentialMatching.overlap", overlap,
                         "--SequentialMatching.loop_detection", "0", NULL};
    char **match = o->sequential_overlap ? match_seq : match_all;
    char *map[] = {colmap, "mapper", "--database_path", db, "--image_path", img, "--output_path", sparse,
                   "--Mapper.num_threads", threads, NULL};
    if ((rc = colmap_step(extract, out->log_path, o, "feature extraction", 1, steps, err)) ||
        (rc = colmap_step(match, out->log_path, o, "matching", 2, steps, err)))
        return rc;
    /* The mapper exits 1 when it builds no model; that is the photos' fault,
     * explained below from the models it left (none). */
    rc = colmap_step(map, out->log_path, o, "mapping", 3, steps, err);
    if (rc && !log_mentions(out->log_path, "failed to create sparse model")) return rc;
    sy_colmap_pose *poses = NULL;
    size_t n = 0;
    pick_model(ws, out->model_dir, sizeof out->model_dir, &poses, &n, err);
    out->n_registered = n;
    if (n == 0) {
        free(poses);
        int no_pair = log_mentions(out->log_path, "No good initial image pair");
        return sy_fail(err, SY_EINPUT,
                       "%s: COLMAP built no model from %zu photos: %s; see %s", images_dir, out->n_images,
                       no_pair ? "no pair of photos overlaps enough to start from (too little overlap or texture)"
                               : "too few features matched between the photos",
                       out->log_path);
    }
    if ((double)n < o->min_registered * (double)out->n_images) {
        free(poses);
        return sy_fail(err, SY_EINPUT,
                       "%s: COLMAP registered only %zu of %zu photos (want %.0f%%): the rest do not overlap the "
                       "others enough; see %s",
                       images_dir, n, out->n_images, 100 * o->min_registered, out->log_path);
    }
    if (cuda) {
        char fused[4300];
        snprintf(fused, sizeof fused, "%.4200s/fused.ply", dense);
        char *undistort[] = {colmap, "image_undistorter", "--image_path", img, "--input_path", out->model_dir,
                             "--output_path", dense, NULL};
        char *stereo[] = {colmap, "patch_match_stereo", "--workspace_path", dense, NULL};
        char *fuse[] = {colmap, "stereo_fusion", "--workspace_path", dense, "--output_path", fused, NULL};
        if ((rc = colmap_step(undistort, out->log_path, o, "undistortion", 4, steps, err)) ||
            (rc = colmap_step(stereo, out->log_path, o, "dense stereo", 5, steps, err)) ||
            (rc = colmap_step(fuse, out->log_path, o, "fusion", 6, steps, err)) ||
            (rc = sy_read_cloud(fused, &out->cloud, err))) {
            free(poses);
            return rc;
        }
        out->dense = 1;
    } else if ((rc = sy_read_colmap_dir(out->model_dir, &out->cloud, err))) {
        free(poses);
        return rc;
    }
    rc = to_sylva_frame(images_dir, o, poses, n, out, err);
    free(poses);
    if (rc) sy_photogrammetry_result_free(out);
    return rc;
}
