/* sylva info FILE...: what a scan holds, with bounds computed from the points. */
#include <stdio.h>
#include <string.h>

#include "pipeline/commands.h"
#include "stages/core/json.h"
#include "stages/ingest/ingest.h"

static const sy_cmd_spec spec = {
    "info", "FILE...", "Describe point-cloud files: format, version, point count, bounds, attributes, CRS/VLRs.",
    "Bounds are computed from the points, never copied from headers; an uncompressed LAS is\n"
    "streamed (headers, then one pass over the records, bounded memory), other formats read whole. With --json, one\n"
    "object per file (an array when several files are given) with flat keys: path, format,\n"
    "version, point_format and global_encoding (LAS), point_count, header_point_count,\n"
    "bounds_min, bounds_max, attributes, crs, vlrs.",
    NULL, 1, -1};

static void print_json(sy_json *j, const char *path, const sy_cloud *c, size_t n, const double lo[3],
                       const double hi[3])
{
    char attrs[1024];
    sy_cloud_attribute_names(c, attrs, sizeof attrs);
    sy_json_object(j, NULL);
    sy_json_string(j, "path", path);
    sy_json_string(j, "format", c->meta.format);
    sy_json_string(j, "version", c->meta.version);
    if (c->meta.point_format >= 0) sy_json_int(j, "point_format", c->meta.point_format);
    if (strcmp(c->meta.format, "LAS") == 0) sy_json_int(j, "global_encoding", c->meta.las_global_encoding);
    sy_json_int(j, "point_count", (long long)n);
    sy_json_int(j, "header_point_count", (long long)c->meta.header_count);
    sy_json_numbers(j, "bounds_min", lo, 3);
    sy_json_numbers(j, "bounds_max", hi, 3);
    sy_json_array(j, "attributes");
    for (char *s = attrs, *e; *s; s = e + (*e != 0)) {
        e = strchr(s, ',');
        if (!e) e = s + strlen(s);
        char name[64];
        snprintf(name, sizeof name, "%.*s", (int)(e - s), s);
        sy_json_string(j, NULL, name);
    }
    sy_json_end(j);
    sy_json_string(j, "crs", c->meta.crs);
    sy_json_string(j, "vlrs", c->meta.vlr_summary);
    sy_json_end(j);
}

static void print_text(const char *path, const sy_cloud *c, size_t n, const double lo[3], const double hi[3])
{
    char attrs[1024];
    sy_cloud_attribute_names(c, attrs, sizeof attrs);
    printf("%s\n", path);
    printf("  format       %s %s", c->meta.format, c->meta.version);
    if (c->meta.point_format >= 0) printf(", point format %d", c->meta.point_format);
    if (strcmp(c->meta.format, "LAS") == 0) printf(", global encoding %u", c->meta.las_global_encoding);
    printf("\n  points       %zu", n);
    if (c->meta.header_count && c->meta.header_count != n)
        printf(" (header says %llu)", (unsigned long long)c->meta.header_count);
    printf("\n  bounds min   %.3f %.3f %.3f\n", lo[0], lo[1], lo[2]);
    printf("  bounds max   %.3f %.3f %.3f\n", hi[0], hi[1], hi[2]);
    printf("  extent       %.3f x %.3f x %.3f m\n", hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]);
    printf("  attributes   %s\n", attrs);
    if (c->meta.crs) printf("  crs          %s\n", c->meta.crs);
    if (c->meta.vlr_summary) {
        printf("  vlrs\n");
        for (const char *s = c->meta.vlr_summary; *s;) {
            const char *e = strchr(s, '\n');
            if (!e) e = s + strlen(s);
            printf("    %.*s\n", (int)(e - s), s);
            s = *e ? e + 1 : e;
        }
    }
}

int cmd_info(int argc, char **argv, sy_cli *cli)
{
    const char *files[1024];
    int n, rc;
    if (!sy_cli_begin(&spec, argc, argv, cli, files, 1024, &n, SY_CLI_OUT_NONE, &rc)) return rc;
    sy_json j;
    if (cli->json) {
        sy_json_begin(&j, stdout, 0);
        if (n > 1) sy_json_array(&j, NULL);
    }
    int status = 0, printed = 0;
    for (int i = 0; i < n; i++) {
        sy_cloud c;
        sy_error err = {0};
        size_t np = 0;
        double lo[3], hi[3];
        if (sy_cloud_info(files[i], &c, &np, lo, hi, &err)) {
            status = sy_cli_report(&err);
            continue;
        }
        if (cli->json) print_json(&j, files[i], &c, np, lo, hi);
        else print_text(files[i], &c, np, lo, hi);
        printed = 1;
        sy_cloud_free(&c);
    }
    if (cli->json) {
        if (n > 1) sy_json_end(&j);
        /* A single unreadable file prints nothing on stdout, not a bare newline. */
        if (n > 1 || printed) sy_json_finish(&j);
    }
    return status;
}
