/* pacs.c - the PACS of the settings (pacs.h). */
#include "pacs.h"

#include <netdb.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A name: letters, digits, '-' and '_', 1 to 31 (it is a path segment: /pacs/{name}/studies). */
static bool good_name(const char *s, size_t n)
{
    if (n < 1 || n > 31)
        return false;
    for (size_t k = 0; k < n; k++)
        if (!((s[k] >= 'a' && s[k] <= 'z') || (s[k] >= 'A' && s[k] <= 'Z') || (s[k] >= '0' && s[k] <= '9') ||
              s[k] == '-' || s[k] == '_'))
            return false;
    return true;
}

/* The FILE of "NAME=FILE" for name in list (space-separated), into out ("" none). */
static void value_for(const char *list, const char *name, char *out, size_t cap)
{
    out[0] = 0;
    size_t n = strlen(name);
    for (const char *p = list; *p;) {
        size_t len = strcspn(p, " ");
        if (len > n && p[n] == '=' && !strncmp(p, name, n))
            snprintf(out, cap, "%.*s", (int)(len - n - 1), p + n + 1);
        p += len;
        p += *p == ' ';
    }
}

/* dicom://AET@HOST:PORT into peer (HOST resolved to its address). */
static int dimse_target(const char *name, const char *url, struct dimse_peer *peer, struct sf_err *err)
{
    const char *at = strchr(url, '@'), *colon = at ? strrchr(at, ':') : NULL;
    char host[256];
    int port = colon ? atoi(colon + 1) : 0;
    if (!at || !colon || at - url < 1 || at - url > 16 || port < 1 || port > 65535 || colon - at - 1 < 1 ||
        colon - at - 1 >= (long)sizeof host)
        return sf_fail(err, SF_EINVAL, NULL, "pacs %s: a DIMSE PACS is dicom://AET@HOST:PORT", name);
    snprintf(peer->ae, sizeof peer->ae, "%.*s", (int)(at - url), url);
    snprintf(host, sizeof host, "%.*s", (int)(colon - at - 1), at + 1);
    struct addrinfo hints = {.ai_socktype = SOCK_STREAM}, *ai = NULL;
    if (getaddrinfo(host, NULL, &hints, &ai) || !ai ||
        getnameinfo(ai->ai_addr, ai->ai_addrlen, peer->ip, sizeof peer->ip, NULL, 0, NI_NUMERICHOST)) {
        if (ai)
            freeaddrinfo(ai);
        return sf_fail(err, SF_EINVAL, NULL, "pacs %s: host %s is not found", name, host);
    }
    freeaddrinfo(ai);
    peer->port = port;
    return 0;
}

int pacs_open_all(struct service *svc, struct sf_err *err)
{
    const char *p = svc->cfg.pacs;
    int rc = 0;
    while (!rc && *p) {
        size_t len = strcspn(p, " "), eq = strcspn(p, "=");
        if (eq >= len || !good_name(p, eq)) {
            rc = sf_fail(err, SF_EINVAL, NULL, "pacs %.*s: a PACS is NAME=URL, its name letters, digits, - and _ (31 at "
                         "most)", (int)len, p);
            break;
        }
        if (svc->n_pacs == PACS_MAX) {
            rc = sf_fail(err, SF_ELIMIT, NULL, "over %d PACS", PACS_MAX);
            break;
        }
        struct pacs *all = realloc(svc->pacs, sizeof *all * (size_t)(svc->n_pacs + 1));
        if (!all) {
            rc = sf_fail(err, SF_ENOMEM, NULL, "out of memory for the PACS");
            break;
        }
        svc->pacs = all;
        struct pacs *one = &all[svc->n_pacs];
        memset(one, 0, sizeof *one);
        snprintf(one->name, sizeof one->name, "%.*s", (int)eq, p);
        char url[1024], cred[512];
        snprintf(url, sizeof url, "%.*s", (int)(len - eq - 1), p + eq + 1);
        for (int k = 0; k < svc->n_pacs && !rc; k++)
            if (!strcmp(svc->pacs[k].name, one->name))
                rc = sf_fail(err, SF_EINVAL, NULL, "pacs %s is named twice", one->name);
        value_for(svc->cfg.pacs_credentials, one->name, cred, sizeof cred);
        if (!rc && !strncmp(url, "dicom://", 8)) {
            one->dimse = true;
            rc = dimse_target(one->name, url + 8, &one->peer, err);
        } else if (!rc) {
            struct dicomweb_config c = {url, cred[0] ? cred : NULL, svc->cfg.pacs_cacert[0] ? svc->cfg.pacs_cacert : NULL,
                                        0, 0, 0, 0};
            struct sf_err e = {0};
            if ((rc = dicomweb_open(&c, &one->dw, &e)))
                sf_fail(err, rc, NULL, "pacs %s: %s", one->name, e.message);
            c.request_timeout_s = PACS_SEARCH_TOTAL_S, c.attempts = 1;
            if (!rc && (rc = dicomweb_open(&c, &one->search, &e))) {
                dicomweb_free(one->dw);
                sf_fail(err, rc, NULL, "pacs %s: %s", one->name, e.message);
            }
        }
        if (!rc)
            svc->n_pacs++;
        p += len;
        p += *p == ' ';
    }
    if (rc)
        pacs_close_all(svc);
    return rc;
}

void pacs_close_all(struct service *svc)
{
    for (int k = 0; k < svc->n_pacs; k++)
        dicomweb_free(svc->pacs[k].dw), dicomweb_free(svc->pacs[k].search);
    free(svc->pacs);
    svc->pacs = NULL, svc->n_pacs = 0;
}

const struct pacs *pacs_find(const struct service *svc, const char *name)
{
    for (int k = 0; name && k < svc->n_pacs; k++)
        if (!strcmp(svc->pacs[k].name, name))
            return &svc->pacs[k];
    return NULL;
}

static void pacs_names(const struct service *svc, char *out, size_t cap)
{
    size_t at = 0;
    out[0] = 0;
    for (int k = 0; k < svc->n_pacs && at < cap; k++)
        at += (size_t)snprintf(out + at, cap - at, "%s%s", k == 0 ? "" : k + 1 == svc->n_pacs ? " and " : ", ",
                               svc->pacs[k].name);
    if (!svc->n_pacs)
        snprintf(out, cap, "none (surfd serve --pacs NAME=URL)");
}

int pacs_failed(int rc, struct sf_err *err)
{
    if (rc == SF_EIO || rc == SF_EFORMAT) { /* (SF_EFORMAT: the PACS's answer was not what it should be) */
        rc = SF_EREMOTE;
        if (err)
            err->code = SF_EREMOTE;
    }
    return rc;
}

int pacs_named(const struct service *svc, const char *name, const struct pacs **out, struct sf_err *err)
{
    char names[512];
    if ((*out = pacs_find(svc, name)))
        return 0;
    pacs_names(svc, names, sizeof names);
    return sf_fail(err, SF_EINVAL, "?pacs", "no PACS named \"%.31s\": this node's are %s", name ? name : "", names);
}
