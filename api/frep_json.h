/* frep_json.h - FRep objects as JSON (API.md §Volumes): the tree of primitives and operations
 * of core/iso/frep.h and the grid it is polygonised on.
 *
 *   {"name": "bracket", "bounds": [[x0, y0, z0], [x1, y1, z1]], "cell": h, "alpha": 0,
 *    "frep": NODE}
 *   NODE = {"sphere": {"center": [3], "radius": r}}
 *        | {"ellipsoid": {"center": [3], "radii": [3]}}
 *        | {"box": {"min": [3], "max": [3]}}
 *        | {"cylinder" | "cone": {"base": [3], "axis": [3], "radius": r, "length": l}}
 *        | {"torus": {"center": [3], "axis": [3], "major": R, "minor": r}}
 *        | {"superellipsoid": {"center": [3], "radii": [3], "e1": e, "e2": e}}
 *        | {"halfspace": {"point": [3], "normal": [3]}}
 *        | {"volume": {"model": ID, "scale": s}}   (a stored isosurface model's samples, as edited,
 *                                                  trilinear, minus its iso, times s (default 1))
 *        | {"union" | "intersect": [NODE, ...], "alpha": a}      (alpha: the request's if absent)
 *        | {"subtract": [NODE, NODE, ...], "alpha": a}           (the first minus the others)
 *        | {"blend": [NODE, NODE], "a0": a0, "a1": a1, "a2": a2, "alpha": a}
 *        | {"offset": {"distance": d, "object": NODE}}
 *        | {"transform": {"scale": s | [3], "rotate_deg": [3], "translate": [3], "object": NODE}}
 *
 * Unknown keys are refused (a misspelt "radus" is a 422, not a default). The operations' lists
 * become balanced trees, so evaluation recurses log2(n) deep for a list of n. Errors are 422s
 * whose pointer names the member ("/frep/subtract/1/transform/object/sphere/radius"). */
#ifndef SURFD_FREP_JSON_H
#define SURFD_FREP_JSON_H

#include <stddef.h>

#include "../core/base/err.h"
#include "../core/iso/frep.h"

/* Samples an FRep grid may have: 2^28 (a 645^3 grid, 1 GiB of float32 samples). */
#define FREP_MAX_SAMPLES (1u << 28)

/* Volumes a tree may read (FREP_VOLUME nodes). */
#define FREP_MAX_VOLUMES 8

/* A volume primitive's model: its id and the pointer to its member, for the caller, who reads
 * the model's samples into vols[k] (frep_request_free frees them) and sets its nodes' iso
 * (frep_volume_iso). */
struct frep_ref {
    char model[40];
    char pointer[176];
};

struct frep_request {
    struct frep f;
    char name[128];
    double lo[3], hi[3], cell;
    int dims[3];             /* samples along x, y, z: lo + i cell covers [lo, hi] */
    struct frep_ref refs[FREP_MAX_VOLUMES];
    struct frep_volume vols[FREP_MAX_VOLUMES];
    float *vol_samples[FREP_MAX_VOLUMES]; /* vols[k].v, owned */
    int n_refs;
};

/* The iso of volume k (the model's) into every node that reads it. */
void frep_volume_iso(struct frep_request *r, int k, double iso);

/* Parses an FRep request: 0, or SF_EFORMAT (not JSON), SF_EINVAL (a bad member, with its
 * pointer), SF_ELIMIT (over FREP_MAX_NODES nodes, FREP_MAX_DEPTH levels or FREP_MAX_SAMPLES). */
int frep_parse(const char *buf, size_t len, struct frep_request *r, struct sf_err *err);
void frep_request_free(struct frep_request *r);

/* An FRep model's edit (POST /models/{id}/edit): request (the model's FRep request) with its
 * tree combined with edit's {"op": "union|intersect|subtract", "object": NODE, "alpha": a} (alpha:
 * the request's when absent), as a new request (caller frees); NULL with err (pointers name the
 * edit's members: "/object/sphere/radius"). */
char *frep_combine(const char *request, size_t len, const char *edit, size_t elen, struct sf_err *err);

#endif
