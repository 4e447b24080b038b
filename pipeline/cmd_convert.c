/* sylva convert IN -o OUT: format conversion through the PointCloud noun. */
#include <stdio.h>

#include "pipeline/commands.h"
#include "stages/core/json.h"
#include "stages/ingest/ingest.h"


int cmd_convert(int argc, char **argv, sy_cli *cli)
{
    const char *out_path = NULL;
    const sy_opt opts[] = {
        {"-o", OPT_STRING, &out_path, "OUT", "output file; format from extension (.ply .las .xyz .txt)"},
        {NULL, 0, NULL, NULL, NULL},
    };
    const sy_cmd_spec spec = {
        "convert", "IN -o OUT", "Convert a point cloud between formats, keeping every attribute the target can hold.",
        "Reads anything `sylva info` reads; writes binary PLY, LAS 1.4 (point format 6/7 with\n"
        "extra bytes for named attributes such as treeID) or ASCII XYZ.",
        opts, 1, 1};
    const char *in[1];
    int n;
    int rc = sy_cli_parse(&spec, argc, argv, cli, in, 1, &n);
    if (rc) return rc < 0 ? 0 : rc;
    sy_cli_apply_settings(cli);
    if (!out_path) {
        fprintf(stderr, "sylva convert: -o OUT is required\n");
        return SY_EUSAGE;
    }
    sy_cloud c;
    sy_error err = {0};
    if (sy_read_cloud(in[0], &c, &err)) return sy_cli_report(&err);
    rc = sy_write_cloud(out_path, &c, &err);
    if (rc == SY_OK) {
        if (cli->json) {
            sy_json j;
            sy_json_begin(&j, stdout, 0);
            sy_json_object(&j, NULL);
            sy_json_string(&j, "input", in[0]);
            sy_json_string(&j, "output", out_path);
            sy_json_int(&j, "point_count", (long long)c.n);
            sy_json_end(&j);
            sy_json_finish(&j);
        } else if (!cli->quiet) {
            fprintf(stderr, "wrote %zu points to %s\n", c.n, out_path);
        }
    }
    sy_cloud_free(&c);
    return rc ? sy_cli_report(&err) : 0;
}
