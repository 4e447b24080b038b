/* The subcommand registry: one line per stage command. */
#include "pipeline/cli.h"
#include "pipeline/commands.h"

const sy_command sy_commands[] = {
    {"info", "describe point-cloud files: format, count, bounds, attributes, CRS", cmd_info},
    {"convert", "convert a point cloud between formats (PLY, LAS, LAZ, XYZ)", cmd_convert},
    {"preprocess", "clean a scan: up-axis, crop, voxel, outliers, ground, normals", cmd_preprocess},
    {"segment", "split a plot scan into trees: stems, crowns or canopy watershed, one cloud per tree", cmd_segment},
    {"grow", "grow a procedural species tree (Weber & Penn) and write it as glTF", cmd_grow},
    {"scan", "virtual LiDAR: scan a generated tree or plot, with exact per-point truth", cmd_scan},
    {"eval", "score a reconstruction: skeleton vs truth, model vs points, segmentation, species", cmd_eval},
    {"skeleton", "reconstruct one tree: skeleton, clusters, hulls -> .sylva", cmd_skeleton},
    {"mesh", "mesh a skeleton or QSM (.sylva, .ply, .csv, .json, .obj, TreeQSM) into a glTF tree", cmd_mesh},
    /* The export stage's own name: meshing and glTF export are one command. */
    {"export", "same as mesh: a skeleton, QSM or .sylva file to a game-ready .glb", cmd_mesh},
    {"run", "reconstruct one scanned tree end to end: skeleton, clusters, mesh -> .glb", cmd_run},
    {"batch", "many scans (folders, files, manifests) to trees and a report, on all cores or Slurm, resumable", cmd_batch},
    {"train", "train the species classifier (JointBoost) on labelled tree scans", cmd_train},
    {"classify", "species of scanned trees: probabilities, confidence, spatial voting", cmd_classify},
    {"encode", "write a .sylva tree file from its JSON form or a skeleton/QSM file", cmd_encode},
    {"decode", "summarise a .sylva tree file, or write it out as JSON", cmd_decode},
    {"leaf", "leaf photos to albedo, normal, thickness, translucency and HL2 maps (a species' leaf)", cmd_leaf},
    {"library", "list the species library or show one species (stable ids, names, kinds, files)", cmd_library},
    {"photogrammetry", "photos -> point cloud through COLMAP, levelled and scaled", cmd_photogrammetry},
    {"view", "preview .glb trees in OpenGL (window or headless screenshots), with wind, LOD and the scan", cmd_view},
    {NULL, NULL, NULL},
};
