//! Standard gRPC health checking (`grpc.health.v1.Health`, from the
//! `tonic-health` crate) on the gRPC port, as load balancers and
//! Kubernetes' gRPC probes speak it: SERVING from the start, NOT_SERVING
//! from the first shutdown signal until the gRPC plane stops once the
//! steps in flight are answered, as `/readyz` turns 503. For the server as a whole (the service name `""`, what a probe asks
//! by default) and for `omcl.v1.Localization`. Without a token, as
//! `/healthz` and `/readyz`.
//!
//! Unlike `/readyz`, a full compute queue leaves it SERVING: a gRPC probe
//! is often a liveness probe, and a server restarted for being busy would
//! lose its sessions. A full queue answers frames RESOURCE_EXHAUSTED with
//! a retry hint instead.

use tonic::server::NamedService;
use tonic_health::ServingStatus;
use tonic_health::pb::health_server::HealthServer;
use tonic_health::server::{HealthReporter, HealthService};

use super::proto::localization_server::LocalizationServer;

/// The names reported: the server's and its localization service's.
const NAMES: [&str; 2] = [
    "",
    <LocalizationServer<super::grpc::Service> as NamedService>::NAME,
];

/// Sets what the health service answers.
#[derive(Clone)]
pub struct Health {
    reporter: HealthReporter,
}

impl Health {
    /// SERVING for every name, and the service that answers for them.
    pub async fn serving() -> (Health, HealthServer<HealthService>) {
        let reporter = HealthReporter::new();
        for name in NAMES {
            reporter
                .set_service_status(name, ServingStatus::Serving)
                .await;
        }
        let service = HealthServer::new(HealthService::from_health_reporter(reporter.clone()));
        (Health { reporter }, service)
    }

    /// NOT_SERVING for every name (a shutdown has begun); `Watch` calls
    /// are told at once.
    pub async fn draining(&self) {
        for name in NAMES {
            self.reporter
                .set_service_status(name, ServingStatus::NotServing)
                .await;
        }
    }

    /// Ends every `Watch` call (the server is about to stop; a graceful
    /// stop would otherwise wait for them, which never end by themselves).
    /// A `Check` after this is answered NOT_FOUND.
    pub async fn stop(mut self) {
        for name in NAMES {
            self.reporter.clear_service_status(name).await;
        }
    }
}
