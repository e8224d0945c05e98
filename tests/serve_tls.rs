//! `omcl serve --tls-cert --tls-key`: gRPC over TLS (rustls). A client that
//! trusts the certificate gets answers; a plaintext client gets none.

mod serve_common;

use serve_common::*;
use tonic::transport::{Certificate, Channel, ClientTlsConfig};

use omcl::serve::proto::{self, localization_client::LocalizationClient};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn grpc_over_tls_with_a_token() {
    let f = Fixture::new();
    let key = rcgen::generate_simple_self_signed(vec!["localhost".to_string()]).unwrap();
    let cert_pem = key.cert.pem();
    let (cert, pkey) = (f.dir.path().join("cert.pem"), f.dir.path().join("key.pem"));
    std::fs::write(&cert, &cert_pem).unwrap();
    std::fs::write(&pkey, key.signing_key.serialize_pem()).unwrap();
    let server = Server::start(
        &f,
        &[
            "--tls-cert",
            cert.to_str().unwrap(),
            "--tls-key",
            pkey.to_str().unwrap(),
        ],
    );
    let tls = ClientTlsConfig::new()
        .ca_certificate(Certificate::from_pem(&cert_pem))
        .domain_name("localhost");
    let ch = Channel::from_shared(format!("https://{}", server.grpc))
        .unwrap()
        .tls_config(tls)
        .unwrap()
        .connect()
        .await
        .unwrap();
    let mut c = LocalizationClient::with_interceptor(ch.clone(), Auth::good());
    let maps = c
        .list_maps(proto::ListMapsRequest {})
        .await
        .unwrap()
        .into_inner();
    assert_eq!(maps.maps[0].name, "room");
    // Over TLS the token is still required.
    let mut anon = LocalizationClient::with_interceptor(ch, Auth(None));
    let e = anon.list_maps(proto::ListMapsRequest {}).await.unwrap_err();
    assert_eq!(e.code(), tonic::Code::Unauthenticated);
    // A plaintext client does not get through.
    let plain = Channel::from_shared(format!("http://{}", server.grpc))
        .unwrap()
        .connect()
        .await;
    if let Ok(ch) = plain {
        let mut c = LocalizationClient::with_interceptor(ch, Auth::good());
        assert!(c.list_maps(proto::ListMapsRequest {}).await.is_err());
    }
}
