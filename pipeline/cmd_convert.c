/* sylva convert IN -o OUT: format conversion through the PointCloud noun;
 * LAS to LAZ and back is transcoded file to file instead, so every record
 * byte, VLR and EVLR survives. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline/commands.h"
#include "stages/core/json.h"
#include "stages/ingest/ingest.h"


static void report(const sy_cli *cli, const char *in, const char *out, unsigned long long n)
{
    if (cli->json) {
        sy_json j;
        sy_cli_json_open(&j, in, out);
        sy_json_int(&j, "point_count", (long long)n);
        sy_cli_json_close(&j);
    } else if (!cli->quiet) {
        fprintf(stderr, "wrote %llu points to %s\n", n, out);
    }
}

/* LAS -> .laz and LAZ -> .las, file to file; *done = 0 for anything else. */
static sy_code transcode_las(const char *in, const char *out, const sy_cli *cli, int *done, sy_error *err)
{
    char ext[16];
    sy_extension(out, ext, sizeof ext);
    int to_laz = strcmp(ext, "laz") == 0, to_las = strcmp(ext, "las") == 0;
    *done = 0;
    if ((!to_laz && !to_las) || sy_is_directory(in)) return SY_OK;
    sy_buffer file;
    sy_code rc = sy_read_file(in, &file, err);
    if (rc) return rc;
    int is_las = file.size >= 105 && memcmp(file.data, "LASF", 4) == 0;
    int is_laz = is_las && (file.data[104] & 0xC0) != 0;
    if (!is_las || is_laz == to_laz) {
        sy_buffer_free(&file);
        return SY_OK;
    }
    sy_buffer coded;
    rc = to_laz ? sy_laz_compress_mem(in, file.data, file.size, &coded, err)
                : sy_laz_decompress_mem(in, file.data, file.size, &coded, err);
    sy_buffer_free(&file);
    if (rc) return rc;
    rc = sy_write_file_atomic(out, coded.data, coded.size, err);
    if (rc == SY_OK) {
        const unsigned char *h = coded.data;
        unsigned long long n = (unsigned long long)(h[107] | h[108] << 8 | h[109] << 16) | (unsigned long long)h[110] << 24;
        if (n == 0 && coded.size >= 255 && h[25] >= 4)
            for (int i = 7; i >= 0; i--) n = n << 8 | h[247 + i];
        report(cli, in, out, n);
        *done = 1;
    }
    free(coded.data);
    return rc;
}

int cmd_convert(int argc, char **argv, sy_cli *cli)
{
    const char *out_path = NULL;
    const sy_opt opts[] = {
        {"-o", OPT_STRING, &out_path, "OUT", "output file; format from extension (.ply .las .laz .xyz .txt)"},
        {NULL, 0, NULL, NULL, NULL},
    };
    const sy_cmd_spec spec = {
        "convert", "IN -o OUT", "Convert a point cloud between formats, keeping every attribute the target can hold.",
        "Reads anything `sylva info` reads; writes binary PLY, LAS 1.4 (point format 6/7 with\n"
        "extra bytes for named attributes such as treeID), LAZ or ASCII XYZ. LAS to LAZ and LAZ\n"
        "to LAS keep the file exactly (every record byte, VLR and EVLR); --threads N sets the\n"
        "cores LAZ chunks are coded on.",
        opts, 1, 1};
    const char *in[1];
    int n, rc;
    if (!sy_cli_begin(&spec, argc, argv, cli, in, 1, &n, SY_CLI_OUT_CHECKED, &rc)) return rc;
    sy_error err = {0};
    int transcoded = 0;
    if ((rc = transcode_las(in[0], out_path, cli, &transcoded, &err))) return sy_cli_report(&err);
    if (transcoded) return 0;
    sy_cloud c;
    if (sy_read_cloud(in[0], &c, &err)) return sy_cli_report(&err);
    rc = sy_write_cloud(out_path, &c, &err);
    if (rc == SY_OK) report(cli, in[0], out_path, c.n);
    sy_cloud_free(&c);
    return rc ? sy_cli_report(&err) : 0;
}
