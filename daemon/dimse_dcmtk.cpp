// dimse_dcmtk.cpp - the storage SCP of dimse.h on DCMTK's dcmnet: a DcmSCPPool listens, and each
// association runs in a DcmThreadSCP of the pool's threads. Hand-written only where surfd decides:
// who may associate (AE title and address both, from the peers), where an instance goes (a spool
// file, written by DCMTK as received), when it is too long (aborted as it passes the cap), and
// the status the sender hears (the store function's, after the instance is stored). One SCP a
// process: the pool makes its workers by default constructor, so they find it in `node`.
#include <dcmtk/config/osconfig.h>
#include <dcmtk/dcmdata/dcuid.h>
#include <dcmtk/dcmnet/dstorscu.h>
#include <dcmtk/dcmnet/scppool.h>
#include <dcmtk/dcmnet/scpthrd.h>
#include <dcmtk/oflog/oflog.h>

#include "dimse.h"

#include <atomic>
#include <cstdio>
#include <cstring>
#include <string>
#include <thread>
#include <unistd.h>
#include <vector>

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
};

extern "C" int dimse_scp_start(const struct dimse_config *c, struct dimse_scp **out, struct sf_err *err)
{
    *out = nullptr;
    if (node)
        return sf_fail(err, SF_EIO, NULL, "a DICOM node is running already");
    OFLog::configure(OFLogger::FATAL_LOG_LEVEL); /* DCMTK's own log is not the daemon's (daemon/log.h) */
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
    s->listener = std::thread([s] { s->pool.listen(); });
    *out = s;
    return 0;
}

extern "C" void dimse_scp_stop(struct dimse_scp *s)
{
    if (!s)
        return;
    s->pool.stopAfterCurrentAssociations();
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
        scu.setACSETimeout(timeout_s);
        scu.setDIMSEBlockingMode(DIMSE_NONBLOCKING);
        scu.setDIMSETimeout(timeout_s);
        scu.setConnectionTimeout((Sint32)timeout_s);
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
