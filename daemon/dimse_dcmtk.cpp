// dimse_dcmtk.cpp - the storage SCP of dimse.h on DCMTK's dcmnet: a DcmSCPPool listens, and each
// association runs in a DcmThreadSCP of the pool's threads. Hand-written only where surfd decides:
// who may associate (AE title and address both, from the peers), where an instance goes (a spool
// file, written by DCMTK as received), when it is too long (aborted as it passes the cap), and
// the status the sender hears (the store function's, after the instance is stored). One SCP a
// process: the pool makes its workers by default constructor, so they find it in `node`.
// The SCU side: C-STORE by DCMTK's storage SCU, C-FIND and C-GET by its DcmSCU, each on an
// association of its own made by the calling thread.
#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcdeftag.h>
#include <dcmtk/dcmdata/dcjson.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmnet/dstorscu.h>
#include <dcmtk/dcmnet/scppool.h>
#include <dcmtk/dcmnet/scpthrd.h>
#include <dcmtk/dcmnet/scu.h>
#include <dcmtk/oflog/oflog.h>

#include "dimse.h"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <sstream>
#include <pthread.h>
#include <string>
#include <thread>
#include <climits>
#include <sys/stat.h>
#include <unistd.h>
#include <vector>

namespace {

/* DCMTK's own log is not the daemon's (daemon/log.h), and at its levels below FATAL it would
 * print a C-FIND's keys, which name patients: silenced once for the process, by whichever of the
 * SCP or an SCU comes first. */
void quiet_dcmtk()
{
    static std::once_flag once;
    std::call_once(once, [] { OFLog::configure(OFLogger::FATAL_LOG_LEVEL); });
}

} // namespace

extern "C" void dimse_global_init(void)
{
    setenv("TCP_NODELAY", "1", 0);
    quiet_dcmtk();
}

namespace {

struct node_config {
    std::string ae, spool;
    std::vector<dimse_peer> peers;
    size_t max_bytes;
    dimse_store_fn store;
    void *arg;
    std::atomic<unsigned long> serial{0};
};

node_config *node; /* the running SCP's (dimse_scp_start to dimse_scp_stop) */

/* The transfer syntaxes accepted, the preferred first: uncompressed, then every compression
 * api/series_dcmtk.cpp and frames_dcmtk.cpp decode (instances are stored as they came). */
const char *const SYNTAXES[] = {
    UID_LittleEndianExplicitTransferSyntax, UID_LittleEndianImplicitTransferSyntax, UID_BigEndianExplicitTransferSyntax,
    UID_RLELosslessTransferSyntax, UID_JPEGProcess14SV1TransferSyntax, UID_JPEGProcess14TransferSyntax,
    UID_JPEGProcess1TransferSyntax, UID_JPEGProcess2_4TransferSyntax, UID_JPEGLSLosslessTransferSyntax,
    UID_JPEGLSLossyTransferSyntax, UID_JPEG2000LosslessOnlyTransferSyntax, UID_JPEG2000TransferSyntax,
    "1.2.840.10008.1.2.4.201", "1.2.840.10008.1.2.4.202", "1.2.840.10008.1.2.4.203"}; /* HTJ2K */

class NodeSCP : public DcmThreadSCP {
  public:
    NodeSCP() = default;

  protected:
    OFBool checkCalledAETitleAccepted(const OFString &called) override { return called == node->ae.c_str(); }

    OFBool checkCallingAETitleAccepted(const OFString &calling) override
    {
        OFString ip = getPeerIP();
        for (const dimse_peer &p : node->peers)
            if (calling == p.ae && ip == p.ip)
                return OFTrue;
        return OFFalse;
    }

    OFCondition handleIncomingCommand(T_DIMSE_Message *msg, const DcmPresentationContextInfo &info) override
    {
        if (msg->CommandField == DIMSE_C_ECHO_RQ)
            return handleECHORequest(msg->msg.CEchoRQ, info.presentationContextID);
        if (msg->CommandField == DIMSE_C_STORE_RQ)
            return store(msg->msg.CStoreRQ, info.presentationContextID);
        return DcmThreadSCP::handleIncomingCommand(msg, info); /* refused as not supported */
    }

    /* DCMTK 3.6.7's pool makes a joinable thread for each association and never joins it (fixed
     * upstream in 2025, not in Debian's): each would keep its stack. Detached as its association
     * ends, the thread's resources go with it. */
    void notifyAssociationTermination() override
    {
        DcmThreadSCP::notifyAssociationTermination();
        pthread_detach(pthread_self());
    }

    void notifyRECEIVEProgress(const unsigned long bytes) override
    {
        if (bytes > node->max_bytes && !over_) {
            over_ = true;
            abortAssociation(); /* the receive then fails; DCMTK drops the association */
        }
    }

  private:
    bool over_ = false;

    OFCondition store(T_DIMSE_C_StoreRQ &rq, T_ASC_PresentationContextID pc)
    {
        char path[4096];
        snprintf(path, sizeof path, "%s/in-%d-%lu.dcm", node->spool.c_str(), (int)getpid(),
                 node->serial.fetch_add(1));
        over_ = false;
        OFCondition c = receiveSTORERequest(rq, pc, OFString(path));
        if (c.bad()) {
            unlink(path); /* (DCMTK removes it on its own errors; an abort may leave it) */
            return c;
        }
        unsigned status = node->store(path, getPeerAETitle().c_str(), rq.AffectedSOPInstanceUID, node->arg);
        unlink(path);
        return sendSTOREResponse(pc, rq, (Uint16)status);
    }
};

} // namespace

struct dimse_scp {
    DcmSCPPool<NodeSCP> pool;
    node_config cfg;
    std::thread listener;
    std::atomic<bool> listening{true};
};

extern "C" int dimse_scp_start(const struct dimse_config *c, struct dimse_scp **out, struct sf_err *err)
{
    *out = nullptr;
    if (node)
        return sf_fail(err, SF_EIO, NULL, "a DICOM node is running already");
    quiet_dcmtk();
    dimse_scp *s;
    try {
        s = new dimse_scp;
        s->cfg.ae = c->ae_title, s->cfg.spool = c->spool;
        s->cfg.peers.assign(c->peers, c->peers + c->n_peers);
        s->cfg.max_bytes = c->max_bytes, s->cfg.store = c->store, s->cfg.arg = c->arg;
        DcmSCPConfig &cfg = s->pool.getConfig();
        cfg.setAETitle(c->ae_title);
        cfg.setPort((Uint16)c->port);
        cfg.setConnectionBlockingMode(DUL_NOBLOCK); /* wakes each second: a stop is seen */
        cfg.setConnectionTimeout(1);
        cfg.setDIMSEBlockingMode(DIMSE_NONBLOCKING);
        cfg.setDIMSETimeout(60); /* a sender silent for a minute mid-instance is dropped */
        cfg.setACSETimeout(30);
        cfg.setHostLookupEnabled(OFFalse);
        cfg.setProgressNotificationMode(OFTrue);
        OFList<OFString> xfers;
        for (const char *x : SYNTAXES)
            xfers.push_back(x);
        OFList<OFString> echo;
        echo.push_back(UID_LittleEndianExplicitTransferSyntax);
        echo.push_back(UID_LittleEndianImplicitTransferSyntax);
        cfg.addPresentationContext(UID_VerificationSOPClass, echo);
        for (int k = 0; k < numberOfDcmAllStorageSOPClassUIDs; k++)
            cfg.addPresentationContext(dcmAllStorageSOPClassUIDs[k], xfers);
        s->pool.setMaxThreads((Uint16)(c->max_associations > 0 ? c->max_associations : 4));
    } catch (const std::bad_alloc &) {
        return sf_fail(err, SF_ENOMEM, NULL, "out of memory for the DICOM node");
    }
    node = &s->cfg;
    /* the port is bound in listen(): tried here first, so a taken one is said at start */
    T_ASC_Network *probe = nullptr;
    OFCondition bound = ASC_initializeNetwork(NET_ACCEPTOR, c->port, 1, &probe);
    if (bound.bad()) {
        node = nullptr;
        delete s;
        return sf_fail(err, SF_EIO, NULL, "the DICOM port %d cannot be listened on: %s", c->port, bound.text());
    }
    ASC_dropNetwork(&probe);
    s->listener = std::thread([s] {
        s->pool.listen();
        s->listening = false;
    });
    *out = s;
    return 0;
}

extern "C" void dimse_scp_stop(struct dimse_scp *s)
{
    if (!s)
        return;
    /* listen() sets its run mode as it starts: a stop asked before then would be lost, so it is
     * asked again until the listener is out (it wakes each second: the connection timeout) */
    while (s->listening) {
        s->pool.stopAfterCurrentAssociations();
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    if (s->listener.joinable())
        s->listener.join();
    node = nullptr;
    delete s;
}

namespace {

/* DCMTK's storage SCU, each instance's response status kept by its place in the list. */
class SendSCU : public DcmStorageSCU {
  public:
    std::vector<std::string> paths;
    unsigned *statuses = nullptr;

  protected:
    void notifySOPInstanceSent(const TransferEntry &e) override
    {
        for (size_t k = 0; k < paths.size(); k++)
            if (e.Filename.getCharPointer() && paths[k] == e.Filename.getCharPointer())
                statuses[k] = e.ResponseStatusCode;
    }
};

} // namespace

extern "C" int dimse_send(const struct dimse_peer *peer, const char *our_ae, const char *const *paths, int n,
                          unsigned timeout_s, unsigned *statuses, struct sf_err *err)
{
    for (int k = 0; k < n; k++)
        statuses[k] = DIMSE_NOT_SENT;
    try {
        SendSCU scu;
        scu.statuses = statuses;
        scu.setAETitle(our_ae);
        scu.setPeerAETitle(peer->ae);
        scu.setPeerHostName(peer->ip);
        scu.setPeerPort((Uint16)peer->port);
        quiet_dcmtk();
        scu.setACSETimeout(timeout_s);
        scu.setDIMSEBlockingMode(DIMSE_NONBLOCKING);
        scu.setDIMSETimeout(timeout_s);
        scu.setConnectionTimeout(DIMSE_CONNECT_TIMEOUT_S);
        for (int k = 0; k < n; k++) {
            scu.paths.emplace_back(paths[k]);
            if (scu.addDicomFile(paths[k], ERM_fileOnly, OFFalse).bad())
                statuses[k] = DIMSE_NOT_SENT;
        }
        OFCondition c = scu.addPresentationContexts();
        if (c.good())
            c = scu.initNetwork();
        if (c.good())
            c = scu.negotiateAssociation();
        if (c.bad())
            return sf_fail(err, SF_EIO, NULL, "the association with %s at %s:%d failed: %s", peer->ae, peer->ip,
                           peer->port, c.text());
        c = scu.sendSOPInstances();
        scu.releaseAssociation();
        if (c.bad())
            return sf_fail(err, SF_EIO, NULL, "sending to %s failed: %s", peer->ae, c.text());
        return 0;
    } catch (const std::bad_alloc &) {
        return sf_fail(err, SF_ENOMEM, NULL, "out of memory for the association");
    }
}

namespace {

/* DcmSCU keeps its association private, and its abortAssociation() frees it while DCMTK's receive
 * loop, which calls notifyRECEIVEProgress, still uses it. Stopping a receive as it passes a cap
 * needs ASC_abortAssociation on the live association alone (what DcmSCP's abortAssociation does
 * for the node's SCP); an explicit instantiation may name a private member ([temp.explicit]), so
 * this reads DcmSCU::m_assoc without a change to DCMTK. */
template <typename Tag, typename Tag::type M> struct grant {
    friend typename Tag::type member(Tag) { return M; }
};
struct scu_assoc {
    typedef T_ASC_Association *DcmSCU::*type;
    friend type member(scu_assoc);
};
template struct grant<scu_assoc, &DcmSCU::m_assoc>;

/* An SCU of ours: the peer and timeouts set, DCMTK's progress calls used to cap what one message
 * may bring (cap_, set before each) and to poll a stop; stop() ends the association at once. */
class PacsSCU : public DcmSCU {
  public:
    PacsSCU(const dimse_peer *peer, const char *our_ae, unsigned timeout_s)
    {
        quiet_dcmtk();
        setAETitle(our_ae);
        setPeerAETitle(peer->ae);
        setPeerHostName(peer->ip);
        setPeerPort((Uint16)peer->port);
        setACSETimeout(timeout_s);
        setDIMSEBlockingMode(DIMSE_NONBLOCKING);
        setDIMSETimeout(timeout_s);
        setConnectionTimeout(DIMSE_CONNECT_TIMEOUT_S);
        setProgressNotificationMode(OFTrue);
    }
    ~PacsSCU() override
    {
        if (isConnected())
            abortAssociation();
    }
    /* The association made: 0, or SF_EIO naming the peer (its down, its refusal, its lack of
     * the presentation context that abstract names). */
    int open(const dimse_peer *peer, const char *abstract, const char *what, T_ASC_PresentationContextID *pc,
             sf_err *err)
    {
        OFCondition c = initNetwork();
        if (c.good())
            c = negotiateAssociation();
        if (c.bad())
            return sf_fail(err, SF_EIO, NULL, "the association with the PACS %s at %s:%d failed: %s", peer->ae,
                           peer->ip, peer->port, c.text());
        if (!(*pc = findPresentationContextID(abstract, "")))
            return sf_fail(err, SF_EIO, NULL, "the PACS %s at %s:%d does not accept %s from this node", peer->ae,
                           peer->ip, peer->port, what);
        return 0;
    }
    void stop()
    {
        T_ASC_Association *a = this->*member(scu_assoc());
        if (a && !stopped_)
            ASC_abortAssociation(a);
        stopped_ = true;
    }
    bool stopped() const { return stopped_; }
    bool over = false;       /* the cap was passed (and the association stopped) */
    unsigned long cap_ = 0;  /* bytes one message may bring; 0: no cap */

  protected:
    void notifyRECEIVEProgress(const unsigned long bytes) override
    {
        if (cap_ && bytes > cap_ && !over) {
            over = true;
            stop();
        }
    }

  private:
    bool stopped_ = false;
};

const char *const QUERY_SYNTAXES[] = {UID_LittleEndianExplicitTransferSyntax, UID_LittleEndianImplicitTransferSyntax};

OFList<OFString> syntaxes(const char *const *v, size_t n)
{
    OFList<OFString> l;
    for (size_t k = 0; k < n; k++)
        l.push_back(v[k]);
    return l;
}

/* ---- C-FIND ---- */

class FindSCU : public PacsSCU {
  public:
    using PacsSCU::PacsSCU;
    std::string json = "[";
    long skip = 0, limit = DIMSE_MAX_MATCHES, kept = 0;
    bool cancelled = false, too_long = false, too_slow = false;
    Uint16 status = 0;
    /* the whole search's end: a PACS dripping a match every 29 s would keep a checks thread forever */
    std::chrono::steady_clock::time_point deadline =
        std::chrono::steady_clock::now() + std::chrono::seconds(DIMSE_SEARCH_TOTAL_S);

  protected:
    OFCondition handleFINDResponse(const T_ASC_PresentationContextID pc, QRResponse *r, OFBool &wait) override
    {
        OFCondition c = DcmSCU::handleFINDResponse(pc, r, wait);
        if (!r)
            return c;
        status = r->m_status;
        if (!DICOM_PENDING_STATUS(r->m_status) || !r->m_dataset || cancelled)
            return c;
        if (skip > 0) {
            skip--;
        } else {
            DcmDataset *d = r->m_dataset;
            delete d->remove(DCM_QueryRetrieveLevel); /* the query's, not the study's (QIDO has none) */
            d->convertToUTF8(); /* (one it cannot convert is refused by the reader of the answer) */
            std::ostringstream one;
            DcmJsonFormatCompact format(OFFalse);
            one << '{'; /* (a data set's writeJson writes its elements alone) */
            d->writeJson(one, format);
            one << '}';
            if (json.size() + one.str().size() + 2 > DIMSE_MAX_ANSWER)
                too_long = true;
            else
                json += (kept++ ? "," : "") + one.str();
        }
        too_slow = too_slow || std::chrono::steady_clock::now() > deadline;
        if ((kept >= limit || too_long || too_slow) && wait) {
            sendCANCELRequest(pc); /* the PACS ends with a Cancel status; later matches are not kept */
            cancelled = true;
        }
        return c;
    }
};

/* A key's attribute: a keyword, or 8 hex digits. */
bool key_tag(const char *name, DcmTag &tag)
{
    size_t n = strlen(name);
    if (n == 8 && strspn(name, "0123456789abcdefABCDEF") == 8) {
        unsigned long v = strtoul(name, NULL, 16);
        tag = DcmTag((Uint16)(v >> 16), (Uint16)(v & 0xffff));
        return true;
    }
    return DcmTag::findTagFromName(name, tag).good();
}

const DcmTagKey STUDY_KEYS[] = {DCM_StudyInstanceUID, DCM_StudyDate, DCM_StudyTime, DCM_StudyDescription,
                                DCM_AccessionNumber, DCM_PatientID, DCM_PatientName, DCM_ModalitiesInStudy,
                                DCM_NumberOfStudyRelatedSeries, DCM_NumberOfStudyRelatedInstances};
const DcmTagKey SERIES_KEYS[] = {DCM_StudyInstanceUID, DCM_SeriesInstanceUID, DCM_Modality, DCM_SeriesNumber,
                                 DCM_SeriesDescription, DCM_NumberOfSeriesRelatedInstances};

/* The query's data set from the keys: 0, or SF_EINVAL at the key. */
int query_keys(DcmDataset &q, FindSCU &scu, const dimse_key *keys, int n_keys, sf_err *err)
{
    for (int k = 0; k < n_keys; k++) {
        const char *name = keys[k].name, *value = keys[k].value ? keys[k].value : "";
        char ptr[64];
        snprintf(ptr, sizeof ptr, "?%.60s", name);
        if (!strcmp(name, "limit") || !strcmp(name, "offset")) {
            char *end;
            long v = strtol(value, &end, 10);
            if (!*value || *end || v < 0 || (v == 0 && name[0] == 'l'))
                return sf_fail(err, SF_EINVAL, ptr, "%s is a whole number (limit at least 1)", name);
            if (name[0] == 'l')
                scu.limit = v < DIMSE_MAX_MATCHES ? v : DIMSE_MAX_MATCHES;
            else
                scu.skip = v;
            continue;
        }
        if (!strcmp(name, "fuzzymatching"))
            continue;
        bool include = !strcmp(name, "includefield");
        std::string list = include ? value : name;
        for (size_t at = 0; at <= list.size();) {
            size_t comma = list.find(',', at);
            std::string one = list.substr(at, comma == std::string::npos ? std::string::npos : comma - at);
            at = comma == std::string::npos ? list.size() + 1 : comma + 1;
            DcmTag tag;
            if (include && one == "all")
                continue; /* C-FIND returns only what it is asked: the usual keys stand for all */
            if (!key_tag(one.c_str(), tag) || tag.getGroup() <= 0x0002 || tag == DCM_QueryRetrieveLevel ||
                tag.getEVR() == EVR_SQ || tag.getEVR() == EVR_UNKNOWN || tag.isPrivate())
                return sf_fail(err, SF_EINVAL, ptr, "%.60s is not an attribute a C-FIND matches or returns (a keyword "
                               "of DICOM's dictionary, or its tag as 8 hex digits; no sequence)", one.c_str());
            if (q.putAndInsertString(tag, include ? "" : value).bad())
                return sf_fail(err, SF_EINVAL, ptr, "%.60s's value cannot be a matching key", one.c_str());
        }
    }
    return 0;
}

} // namespace

extern "C" int dimse_find(const struct dimse_peer *peer, const char *our_ae, enum dimse_level level,
                          const char *study_uid, const struct dimse_key *keys, int n_keys, char **json, size_t *len,
                          struct sf_err *err)
{
    *json = nullptr, *len = 0;
    try {
        FindSCU scu(peer, our_ae, DIMSE_QUERY_TIMEOUT_S);
        DcmDataset q;
        q.putAndInsertString(DCM_QueryRetrieveLevel, level == DIMSE_SERIES ? "SERIES" : "STUDY");
        const DcmTagKey *ret = level == DIMSE_SERIES ? SERIES_KEYS : STUDY_KEYS;
        size_t n_ret = level == DIMSE_SERIES ? sizeof SERIES_KEYS / sizeof *SERIES_KEYS
                                             : sizeof STUDY_KEYS / sizeof *STUDY_KEYS;
        for (size_t k = 0; k < n_ret; k++)
            q.insertEmptyElement(ret[k]);
        int rc = query_keys(q, scu, keys, n_keys, err);
        if (!rc && study_uid)
            q.putAndInsertString(DCM_StudyInstanceUID, study_uid);
        if (rc)
            return rc;
        scu.addPresentationContext(UID_FINDStudyRootQueryRetrieveInformationModel, syntaxes(QUERY_SYNTAXES, 2));
        T_ASC_PresentationContextID pc = 0;
        if ((rc = scu.open(peer, UID_FINDStudyRootQueryRetrieveInformationModel, "C-FIND (Study Root)", &pc, err)))
            return rc;
        scu.cap_ = DIMSE_MAX_MATCH_BYTES;
        OFCondition c = scu.sendFINDRequest(pc, &q, NULL);
        if (scu.over)
            return sf_fail(err, SF_ELIMIT, NULL, "a C-FIND response of the PACS %s is over %u bytes", peer->ae,
                           DIMSE_MAX_MATCH_BYTES);
        if (c.bad())
            return sf_fail(err, SF_EIO, NULL, "the C-FIND of the PACS %s at %s:%d broke off: %s", peer->ae, peer->ip,
                           peer->port, c.text());
        if (scu.too_long)
            return sf_fail(err, SF_ELIMIT, NULL, "the PACS %s matched over %u bytes of studies: narrow the search",
                           peer->ae, DIMSE_MAX_ANSWER);
        if (scu.too_slow)
            return sf_fail(err, SF_EIO, NULL, "the PACS %s took over %d s to answer the C-FIND", peer->ae,
                           DIMSE_SEARCH_TOTAL_S);
        if (scu.status != STATUS_Success && !(scu.cancelled && scu.status == STATUS_FIND_Cancel_MatchingTerminatedDueToCancelRequest))
            return sf_fail(err, SF_EIO, NULL, "the PACS %s answered the C-FIND with status 0x%04x", peer->ae,
                           (unsigned)scu.status);
        scu.releaseAssociation();
        scu.json += "]";
        if (!(*json = (char *)malloc(scu.json.size() + 1)))
            return sf_fail(err, SF_ENOMEM, NULL, "out of memory for the PACS's answer");
        memcpy(*json, scu.json.c_str(), scu.json.size() + 1);
        *len = scu.json.size();
        return 0;
    } catch (const std::bad_alloc &) {
        return sf_fail(err, SF_ENOMEM, NULL, "out of memory for the C-FIND");
    }
}

namespace {

/* ---- C-GET ---- */

/* The instances come back on our association by C-STORE: DcmSCU's bit-preserving mode writes
 * each to a file as received (never whole in memory), in our handleSTORERequestFile, which hands
 * it over before DcmSCU sends its status (success, or 0xC000 for a failure of ours). */
class GetSCU : public PacsSCU {
  public:
    using PacsSCU::PacsSCU;
    const dimse_retrieve *rq = nullptr;
    sf_err *err = nullptr;
    int rc = 0, handed = 0;
    long remaining = -1, completed = 0, failed = 0, warning = 0;
    Uint16 status = 0;
    bool final_seen = false;

  protected:
    OFCondition handleSTORERequestFile(T_ASC_PresentationContextID *pc, const OFString &,
                                       T_DIMSE_C_StoreRQ *req) override
    {
        if (rc)
            return EC_IllegalCall;
        char path[4096];
        snprintf(path, sizeof path, "%s/get-%06d.dcm", rq->dir, handed + 1); /* (not the UID: the PACS names it) */
        over = false;
        OFCondition c = DcmSCU::handleSTORERequestFile(pc, OFString(path), req);
        struct stat st;
        uint64_t n = c.good() && !stat(path, &st) ? (uint64_t)st.st_size : 0;
        /* (the progress call comes after each PDV: an instance of one PDV passes the cap whole) */
        if (c.bad() || over || n > rq->max_instance_bytes) {
            unlink(path);
            rc = over || n > rq->max_instance_bytes
                     ? sf_fail(err, SF_ELIMIT, NULL, "an instance from the PACS is over %llu bytes",
                               (unsigned long long)rq->max_instance_bytes)
                     : sf_fail(err, SF_EIO, NULL, "an instance from the PACS could not be received: %s", c.text());
            return c.bad() ? c : EC_IllegalCall;
        }
        rc = rq->instance(rq->ctx, ++handed, path, n, err);
        unlink(path);
        if (rc)
            return EC_IllegalCall; /* DcmSCU answers 0xC000 and ends the session */
        poll();
        return EC_Normal;
    }

    OFCondition handleCGETResponse(const T_ASC_PresentationContextID pc, RetrieveResponse *r, OFBool &more) override
    {
        OFCondition c = DcmSCU::handleCGETResponse(pc, r, more);
        if (r) {
            status = r->m_status;
            remaining = r->m_numberOfRemainingSubops, completed = r->m_numberOfCompletedSubops;
            failed = r->m_numberOfFailedSubops, warning = r->m_numberOfWarningSubops;
            final_seen = !more;
            if (more)
                poll();
        }
        return c;
    }

  private:
    void poll()
    {
        double total = (double)(completed + (remaining > 0 ? remaining : 0));
        double done = total > 0 ? (double)completed / total : 0;
        if (!rc && sf_poll(rq->progress, done < 1 ? done : 1, err)) {
            rc = SF_ECANCEL;
            stop(); /* DcmSCU's next send or receive then fails and ends the session */
        }
    }
};

} // namespace

extern "C" int dimse_get(const struct dimse_peer *peer, const char *our_ae, const char *study_uid,
                         const char *series_uid, const struct dimse_retrieve *rq, int *n_instances,
                         struct sf_err *err)
{
    *n_instances = 0;
    try {
        GetSCU scu(peer, our_ae, DIMSE_GET_TIMEOUT_S);
        scu.rq = rq, scu.err = err;
        scu.setStorageMode(DCMSCU_STORAGE_BIT_PRESERVING);
        scu.setStorageDir(rq->dir);
        scu.addPresentationContext(UID_GETStudyRootQueryRetrieveInformationModel, syntaxes(QUERY_SYNTAXES, 2));
        /* DCMTK's list of the storage classes an SCU proposes one context each for (at most 120,
         * leaving room in the 128 an association may have), surfd in the SCP role for them */
        OFList<OFString> xfers = syntaxes(SYNTAXES, sizeof SYNTAXES / sizeof *SYNTAXES);
        for (int k = 0; k < numberOfDcmLongSCUStorageSOPClassUIDs; k++)
            scu.addPresentationContext(dcmLongSCUStorageSOPClassUIDs[k], xfers, ASC_SC_ROLE_SCP);
        T_ASC_PresentationContextID pc = 0;
        int rc = scu.open(peer, UID_GETStudyRootQueryRetrieveInformationModel, "C-GET (Study Root)", &pc, err);
        if (rc)
            return rc;
        DcmDataset q;
        q.putAndInsertString(DCM_QueryRetrieveLevel, series_uid ? "SERIES" : "STUDY");
        q.putAndInsertString(DCM_StudyInstanceUID, study_uid);
        if (series_uid)
            q.putAndInsertString(DCM_SeriesInstanceUID, series_uid);
        scu.cap_ = (unsigned long)(rq->max_instance_bytes < ULONG_MAX ? rq->max_instance_bytes : ULONG_MAX);
        OFCondition c = scu.sendCGETRequest(pc, &q, NULL);
        *n_instances = scu.handed;
        if (scu.rc)
            return scu.rc;
        if (c.bad() || !scu.final_seen)
            return sf_fail(err, SF_EIO, NULL, "the C-GET from the PACS %s at %s:%d broke off after %d instances: %s",
                           peer->ae, peer->ip, peer->port, scu.handed, c.bad() ? c.text() : "no final response");
        scu.releaseAssociation();
        if (scu.handed == 0 && scu.completed == 0 && scu.failed == 0 && scu.warning == 0)
            /* (Orthanc answers a UID it does not hold with 0xC000 and no sub-operation) */
            return sf_fail(err, SF_ENOTFOUND, NULL, "the PACS %s holds no instances of that %s (C-GET status 0x%04x)",
                           peer->ae, series_uid ? "series" : "study", (unsigned)scu.status);
        if (scu.failed > 0 || (scu.status != STATUS_Success && !DICOM_WARNING_STATUS(scu.status)))
            return sf_fail(err, SF_EIO, NULL, "the PACS %s sent %d instances and failed %ld (C-GET status 0x%04x)",
                           peer->ae, scu.handed, scu.failed, (unsigned)scu.status);
        return 0;
    } catch (const std::bad_alloc &) {
        return sf_fail(err, SF_ENOMEM, NULL, "out of memory for the C-GET");
    }
}
