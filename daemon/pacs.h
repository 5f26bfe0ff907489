/* pacs.h - the PACS surfd pulls from and sends to (issue 44): `--pacs NAME=URL` names a DICOMweb
 * root (dicomweb.h; its credentials from `--pacs-credentials NAME=FILE`, never a flag's value) or
 * `--pacs NAME=dicom://AET@HOST:PORT`, a DIMSE node (dimse.h: C-STORE to it). Opened once at start
 * (a URL or a credentials file that is wrong stops the start, naming it), read-only after. */
#ifndef SURFD_PACS_H
#define SURFD_PACS_H

#include <stdbool.h>

#include "dicomweb.h"
#include "dimse.h"
#include "service.h"

#define PACS_MAX 16
#define PACS_SEARCH_TOTAL_S 30 /* a search (GET /pacs/{name}/studies) in all, as dimse.h's C-FIND */

struct pacs {
    char name[32];
    bool dimse;              /* dicom://: peer; else dw */
    struct dicomweb *dw;
    struct dicomweb *search; /* dw's settings bounded for a search, which holds a checks thread: 30 s
                              * in all, one attempt */
    struct dimse_peer peer;
};

/* The PACS of cfg.pacs (and their credentials), into svc: 0, or an error said in err. */
int pacs_open_all(struct service *svc, struct sf_err *err);
void pacs_close_all(struct service *svc);
/* The PACS named so, or NULL. */
const struct pacs *pacs_find(const struct service *svc, const char *name);
/* A PACS call's answer as the request's: SF_EIO and SF_EFORMAT (the PACS down, refusing, answering badly) become
 * SF_EREMOTE (502, not surfd's own failure), err's code too; others as they are. */
int pacs_failed(int rc, struct sf_err *err);
/* The PACS a request names (?pacs, or the path's): 0 and *out, or SF_EINVAL at "?pacs" naming those
 * configured. */
int pacs_named(const struct service *svc, const char *name, const struct pacs **out, struct sf_err *err);

#endif
