//! `omcl serve --tls-cert --tls-key`: gRPC and the HTTP control plane over
//! TLS (rustls). A client that trusts the certificate gets answers; a
//! plaintext client gets none.

mod serve_common;

use serve_common::*;
use tonic::transport::{Certificate, Channel, ClientTlsConfig};

use omcl::serve::proto::{self, localization_client::LocalizationClient};

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn grpc_over_tls_with_a_token() {
    let f = Fixture::new();
    let (server, cert_pem) = tls_server(&f, &[]);
    let ch = tls_channel(&server, &cert_pem).await;
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
    // The HTTP control plane is HTTPS with the same certificate: a client
    // that trusts it gets the map list with the token, 401 without; a
    // plaintext request gets no HTTP answer.
    let (status, body) = https_get(&server, &cert_pem, "/v1/maps", Some(TOKEN)).await;
    assert!(status.starts_with("HTTP/1.1 200"), "{status}");
    assert!(body.contains("room"), "{body}");
    let (status, body) = https_get(&server, &cert_pem, "/v1/maps", None).await;
    assert!(status.starts_with("HTTP/1.1 401"), "{status}");
    assert!(!body.contains("room"), "{body}");
    let (status, _) = https_get(&server, &cert_pem, "/healthz", None).await;
    assert!(status.starts_with("HTTP/1.1 200"), "{status}");
    {
        use tokio::io::{AsyncReadExt, AsyncWriteExt};
        let mut tcp = tokio::net::TcpStream::connect(server.http).await.unwrap();
        tcp.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n")
            .await
            .unwrap();
        let mut got = Vec::new();
        let _ = tokio::time::timeout(std::time::Duration::from_secs(5), tcp.read_to_end(&mut got))
            .await;
        assert!(
            !String::from_utf8_lossy(&got).contains("HTTP/1.1 200"),
            "plaintext HTTP answered"
        );
    }
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

/// Over TLS too a connection past `--max-connections` is refused by name
/// (the refusal finds the peer behind the TLS layer's connection info).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_tls_connection_past_the_cap_is_refused_by_name() {
    let f = Fixture::new();
    let (server, cert_pem) = tls_server(&f, &["--max-connections", "1"]);
    let connect = || async {
        LocalizationClient::with_interceptor(tls_channel(&server, &cert_pem).await, Auth::good())
    };
    let mut first = connect().await;
    first.list_maps(proto::ListMapsRequest {}).await.unwrap();
    let mut second = connect().await;
    let e = tokio::time::timeout(
        std::time::Duration::from_secs(20),
        second.list_maps(proto::ListMapsRequest {}),
    )
    .await
    .expect("the refused call was answered")
    .expect_err("a second connection was served");
    assert_eq!(e.code(), tonic::Code::ResourceExhausted, "{e:?}");
    assert!(e.message().contains("--max-connections 1"), "{e:?}");
    first.list_maps(proto::ListMapsRequest {}).await.unwrap();
}

/// A server over TLS with a fresh self-signed certificate for
/// `localhost` (and `extra` arguments), and that certificate's PEM.
fn tls_server(f: &Fixture, extra: &[&str]) -> (Server, String) {
    let key = rcgen::generate_simple_self_signed(vec!["localhost".to_string()]).unwrap();
    let cert_pem = key.cert.pem();
    let (cert, pkey) = (f.dir.path().join("cert.pem"), f.dir.path().join("key.pem"));
    std::fs::write(&cert, &cert_pem).unwrap();
    std::fs::write(&pkey, key.signing_key.serialize_pem()).unwrap();
    let mut args = vec![
        "--tls-cert",
        cert.to_str().unwrap(),
        "--tls-key",
        pkey.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    (Server::start(f, &args), cert_pem)
}

/// A gRPC channel over TLS to `server` on a connection of its own,
/// trusting `cert_pem`.
async fn tls_channel(server: &Server, cert_pem: &str) -> Channel {
    let tls = ClientTlsConfig::new()
        .ca_certificate(Certificate::from_pem(cert_pem))
        .domain_name("localhost");
    Channel::from_shared(format!("https://{}", server.grpc))
        .unwrap()
        .tls_config(tls)
        .unwrap()
        .connect()
        .await
        .unwrap()
}

/// GET `path` over HTTPS from the control plane, trusting `cert_pem`:
/// the status line and the body.
async fn https_get(
    server: &Server,
    cert_pem: &str,
    path: &str,
    token: Option<&str>,
) -> (String, String) {
    use rustls::pki_types::pem::PemObject;
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    use tokio_rustls::rustls;
    let mut roots = rustls::RootCertStore::empty();
    for c in rustls::pki_types::CertificateDer::pem_slice_iter(cert_pem.as_bytes()) {
        roots.add(c.unwrap()).unwrap();
    }
    let provider = std::sync::Arc::new(rustls::crypto::ring::default_provider());
    let cfg = rustls::ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .unwrap()
        .with_root_certificates(roots)
        .with_no_client_auth();
    let connector = tokio_rustls::TlsConnector::from(std::sync::Arc::new(cfg));
    let tcp = tokio::net::TcpStream::connect(server.http).await.unwrap();
    let name = rustls::pki_types::ServerName::try_from("localhost").unwrap();
    let mut tls = connector.connect(name, tcp).await.unwrap();
    let auth = token.map_or(String::new(), |t| format!("Authorization: Bearer {t}\r\n"));
    let req = format!("GET {path} HTTP/1.1\r\nHost: localhost\r\n{auth}Connection: close\r\n\r\n");
    tls.write_all(req.as_bytes()).await.unwrap();
    let mut got = Vec::new();
    let _ = tls.read_to_end(&mut got).await;
    let text = String::from_utf8_lossy(&got).to_string();
    let status = text.lines().next().unwrap_or("").to_string();
    let body = text.split("\r\n\r\n").nth(1).unwrap_or("").to_string();
    (status, body)
}

/// The banner says HTTPS for the control plane; a swapped certificate and
/// key are named as such (it was "--tls-key: no items found").
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn https_is_announced_and_a_swapped_pair_is_named() {
    let f = Fixture::new();
    let key = rcgen::generate_simple_self_signed(vec!["localhost".to_string()]).unwrap();
    let (cert, pkey) = (f.dir.path().join("cert.pem"), f.dir.path().join("key.pem"));
    std::fs::write(&cert, key.cert.pem()).unwrap();
    std::fs::write(&pkey, key.signing_key.serialize_pem()).unwrap();
    let (c, k) = (cert.to_str().unwrap(), pkey.to_str().unwrap());
    let server = Server::start(&f, &["--tls-cert", c, "--tls-key", k]);
    assert!(server.banner.contains(", HTTPS on "), "{}", server.banner);
    drop(server);
    let map = format!("room={}", f.map.to_str().unwrap());
    let run = |cert: &str, key: &str| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_omcl"))
            .args([
                "serve",
                "--map",
                &map,
                "--grpc",
                "127.0.0.1:0",
                "--http",
                "127.0.0.1:0",
            ])
            .args(["--tls-cert", cert, "--tls-key", key])
            .env("OMCL_TOKEN", TOKEN)
            .output()
            .unwrap();
        assert!(!out.status.success(), "{out:?}");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let err = run(k, c);
    assert!(
        err.contains("--tls-cert: the file holds no PEM certificate")
            && err.contains("is it the --tls-key file?"),
        "{err}"
    );
    let err = run(c, c);
    assert!(
        err.contains("--tls-key: the file holds no PEM private key")
            && err.contains("is it the --tls-cert file?"),
        "{err}"
    );
}
