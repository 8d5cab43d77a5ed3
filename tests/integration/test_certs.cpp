#include "tests/integration/test_certs.h"

#include <openssl/bio.h>
#include <openssl/bn.h>
#include <openssl/err.h>
#include <openssl/evp.h>
#include <openssl/pem.h>
#include <openssl/rand.h>
#include <openssl/x509.h>
#include <openssl/x509v3.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <tuple>
#include <utility>

namespace tessera::testing {
namespace {

struct Free {
  void operator()(EVP_PKEY* p) const { EVP_PKEY_free(p); }
  void operator()(X509* p) const { X509_free(p); }
  void operator()(BIO* p) const { BIO_free(p); }
  void operator()(BIGNUM* p) const { BN_free(p); }
  void operator()(ASN1_INTEGER* p) const { ASN1_INTEGER_free(p); }
  void operator()(X509_EXTENSION* p) const { X509_EXTENSION_free(p); }
};
using Key = std::unique_ptr<EVP_PKEY, Free>;
using Cert = std::unique_ptr<X509, Free>;

// Test support: a failure here is a broken environment, not something a test can handle.
void Check(bool ok, const char* what) {
  if (ok) return;
  std::fprintf(stderr, "MakeTestPki: %s failed\n", what);
  ERR_print_errors_fp(stderr);
  std::abort();
}

Key NewKey() {
  Key key(EVP_EC_gen("P-256"));
  Check(key != nullptr, "EVP_EC_gen(P-256)");
  return key;
}

// A positive 159-bit random serial: unique enough that certificates from different runs never
// collide in a client's cache, and short of the 20-octet limit of RFC 5280.
void SetRandomSerial(X509* cert) {
  unsigned char bytes[20];
  Check(RAND_bytes(bytes, sizeof bytes) == 1, "RAND_bytes");
  bytes[0] &= 0x7f;  // keep it positive
  bytes[0] |= 0x01;  // and non-zero
  std::unique_ptr<BIGNUM, Free> bn(BN_bin2bn(bytes, sizeof bytes, nullptr));
  Check(bn != nullptr, "BN_bin2bn");
  std::unique_ptr<ASN1_INTEGER, Free> serial(BN_to_ASN1_INTEGER(bn.get(), nullptr));
  Check(serial != nullptr, "BN_to_ASN1_INTEGER");
  Check(X509_set_serialNumber(cert, serial.get()) == 1, "X509_set_serialNumber");
}

void SetCommonName(X509* cert, const char* cn) {
  X509_NAME* name = X509_get_subject_name(cert);
  Check(X509_NAME_add_entry_by_txt(name, "O", MBSTRING_ASC,
                                   reinterpret_cast<const unsigned char*>("Tessera tests"), -1, -1,
                                   0) == 1,
        "X509_NAME_add_entry_by_txt(O)");
  Check(X509_NAME_add_entry_by_txt(name, "CN", MBSTRING_ASC,
                                   reinterpret_cast<const unsigned char*>(cn), -1, -1, 0) == 1,
        "X509_NAME_add_entry_by_txt(CN)");
}

// Everything but extensions and the signature. Valid from an hour ago, so a test machine whose
// clock is slightly behind still accepts it, for a day.
Cert NewCert(const char* cn, EVP_PKEY* key) {
  Cert cert(X509_new());
  Check(cert != nullptr, "X509_new");
  Check(X509_set_version(cert.get(), X509_VERSION_3) == 1, "X509_set_version");
  SetRandomSerial(cert.get());
  SetCommonName(cert.get(), cn);
  Check(X509_gmtime_adj(X509_getm_notBefore(cert.get()), -60 * 60) != nullptr, "notBefore");
  Check(X509_gmtime_adj(X509_getm_notAfter(cert.get()), 24 * 60 * 60) != nullptr, "notAfter");
  Check(X509_set_pubkey(cert.get(), key) == 1, "X509_set_pubkey");
  return cert;
}

// Adds one extension in openssl.cnf syntax ("critical,CA:TRUE"). `issuer` supplies the
// authority key identifier; the subject's own public key gives the subject key identifier.
void AddExtension(X509* cert, X509* issuer, int nid, const char* value) {
  X509V3_CTX ctx;
  X509V3_set_ctx(&ctx, issuer, cert, nullptr, nullptr, 0);
  std::unique_ptr<X509_EXTENSION, Free> ext(X509V3_EXT_conf_nid(nullptr, &ctx, nid, value));
  Check(ext != nullptr, OBJ_nid2sn(nid));
  Check(X509_add_ext(cert, ext.get(), -1) == 1, "X509_add_ext");
}

void Sign(X509* cert, EVP_PKEY* issuer_key) {
  Check(X509_sign(cert, issuer_key, EVP_sha256()) > 0, "X509_sign");
}

std::string CertPem(X509* cert) {
  std::unique_ptr<BIO, Free> bio(BIO_new(BIO_s_mem()));
  Check(bio != nullptr && PEM_write_bio_X509(bio.get(), cert) == 1, "PEM_write_bio_X509");
  char* data = nullptr;
  const long n = BIO_get_mem_data(bio.get(), &data);
  return std::string(data, static_cast<size_t>(n));
}

std::string KeyPem(EVP_PKEY* key) {
  std::unique_ptr<BIO, Free> bio(BIO_new(BIO_s_mem()));
  Check(bio != nullptr &&
            PEM_write_bio_PrivateKey(bio.get(), key, nullptr, nullptr, 0, nullptr, nullptr) == 1,
        "PEM_write_bio_PrivateKey");
  char* data = nullptr;
  const long n = BIO_get_mem_data(bio.get(), &data);
  return std::string(data, static_cast<size_t>(n));
}

struct Ca {
  Key key;
  Cert cert;
};

Ca MakeCa(const char* cn) {
  Ca ca{NewKey(), nullptr};
  ca.cert = NewCert(cn, ca.key.get());
  X509* c = ca.cert.get();
  Check(X509_set_issuer_name(c, X509_get_subject_name(c)) == 1, "X509_set_issuer_name");
  AddExtension(c, c, NID_basic_constraints, "critical,CA:TRUE,pathlen:0");
  AddExtension(c, c, NID_key_usage, "critical,keyCertSign,cRLSign");
  AddExtension(c, c, NID_subject_key_identifier, "hash");
  Sign(c, ca.key.get());
  return ca;
}

// A leaf signed by `ca`; `extended_usage` is "serverAuth" or "clientAuth", `alt_names` is a
// subjectAltName value or null.
std::pair<std::string, std::string> MakeLeaf(const Ca& ca, const char* cn,
                                             const char* extended_usage, const char* alt_names) {
  Key key = NewKey();
  Cert cert = NewCert(cn, key.get());
  X509* c = cert.get();
  Check(X509_set_issuer_name(c, X509_get_subject_name(ca.cert.get())) == 1, "X509_set_issuer_name");
  AddExtension(c, ca.cert.get(), NID_basic_constraints, "critical,CA:FALSE");
  // ECDSA keys sign the handshake; keyAgreement is never used by TLS 1.2 ECDHE or 1.3.
  AddExtension(c, ca.cert.get(), NID_key_usage, "critical,digitalSignature");
  AddExtension(c, ca.cert.get(), NID_ext_key_usage, extended_usage);
  if (alt_names != nullptr) AddExtension(c, ca.cert.get(), NID_subject_alt_name, alt_names);
  AddExtension(c, ca.cert.get(), NID_subject_key_identifier, "hash");
  AddExtension(c, ca.cert.get(), NID_authority_key_identifier, "keyid:always");
  Sign(c, ca.key.get());
  return {CertPem(c), KeyPem(key.get())};
}

}  // namespace

TestPki MakeTestPki() {
  const Ca ca = MakeCa("Tessera Test CA");
  const Ca other = MakeCa("Tessera Unrelated Test CA");
  TestPki pki;
  pki.ca_cert_pem = CertPem(ca.cert.get());
  pki.other_ca_cert_pem = CertPem(other.cert.get());
  // ::1 too: "localhost" may resolve to the IPv6 loopback first.
  std::tie(pki.server_cert_pem, pki.server_key_pem) =
      MakeLeaf(ca, "localhost", "serverAuth", "DNS:localhost,IP:127.0.0.1,IP:::1");
  std::tie(pki.client_cert_pem, pki.client_key_pem) =
      MakeLeaf(ca, "tessera-test-client", "clientAuth", nullptr);
  return pki;
}

}  // namespace tessera::testing
