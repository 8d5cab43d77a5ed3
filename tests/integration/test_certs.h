#pragma once
// Certificates for TLS and mTLS integration tests, made at test time with OpenSSL's C API so
// no key is ever committed and none expires in the repository.
//
// Note: this is tessera::testing; inside namespace tessera, GoogleTest's namespace must be
// spelled ::testing.
#include <string>

namespace tessera::testing {

// PEM text, ready for grpc::SslServerCredentialsOptions / grpc::SslCredentialsOptions.
// Keys are EC P-256 in PKCS#8 ("BEGIN PRIVATE KEY"), unencrypted. Every certificate is valid
// from an hour ago (tolerates clock skew between test processes) to a day from now, and has
// a random serial.
struct TestPki {
  std::string ca_cert_pem;      // self-signed CA (basicConstraints CA:TRUE, keyCertSign)
  std::string server_cert_pem;  // signed by the CA; CN=localhost; subjectAltName DNS:localhost,
                                // IP:127.0.0.1, IP:::1; serverAuth EKU
  std::string server_key_pem;
  std::string client_cert_pem;  // signed by the CA; CN=tessera-test-client; clientAuth EKU
  std::string client_key_pem;
  std::string other_ca_cert_pem;  // an unrelated CA, for "wrong CA" tests
};

// A fresh PKI on every call (a few milliseconds). Aborts with a message on any OpenSSL
// failure: it is test support, and a broken PKI would only make later failures obscure.
TestPki MakeTestPki();

}  // namespace tessera::testing
