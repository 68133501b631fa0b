//! `sinew certs`: the certificates a lab needs to run a session only the invited can join.
//!
//! Owns: making a certificate authority and one certificate per role, signed by it, as PEM files, and the
//! lab's `zenohd` configuration using the router's ([`write_router_config`]). The role
//! is the certificate's common name, which zenoh's access control matches (`server`, `observer`,
//! `device-<id>`, `router`: see `sinew_protocol::security`); every certificate names the hosts it may be reached at
//! (localhost and the loopback addresses, plus `--host`), because in peer mode each role both accepts and
//! dials, so each certificate serves as a TLS server and a TLS client.
//!
//! Must not: overwrite an existing CA key (a lab that loses it must re-issue every certificate), or write
//! a private key readable by others.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::Context;
use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};
use sinew_protocol::security::{RoleName, TlsFiles};

/// What [`make_lab_certs`] wrote.
#[derive(Debug, Clone, PartialEq)]
pub struct LabCerts {
    /// The folder.
    pub dir: PathBuf,
    /// The CA certificate every role trusts.
    pub ca: PathBuf,
    /// Per role: its common name and files.
    pub roles: Vec<(String, TlsFiles)>,
}

impl LabCerts {
    /// The files of the role with common name `name`.
    pub fn role(&self, name: &str) -> Option<&TlsFiles> {
        self.roles.iter().find(|(n, _)| n == name).map(|(_, f)| f)
    }
}

fn write_private(path: &Path, text: &str) -> anyhow::Result<()> {
    use std::os::unix::fs::OpenOptionsExt;
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .mode(0o600)
        .open(path)
        .with_context(|| format!("writing {}", path.display()))?;
    file.write_all(text.as_bytes())
        .with_context(|| format!("writing {}", path.display()))
}

/// Make a CA and certificates for the server, one observer, a site's router and each device in `device_ids`, into `dir`
/// (created if needed). `hosts` are extra names or addresses the roles are reached at (a site's DNS name).
/// Refuses to overwrite an existing `ca-key.pem`.
pub fn make_lab_certs(
    dir: &Path,
    device_ids: &[String],
    hosts: &[String],
) -> anyhow::Result<LabCerts> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let ca_key_path = dir.join("ca-key.pem");
    anyhow::ensure!(
        !ca_key_path.exists(),
        "{} exists: refusing to replace a lab's CA (use another --out, or remove it and re-issue every \
         certificate)",
        ca_key_path.display()
    );
    let mut names: Vec<RoleName> = vec![RoleName::Server, RoleName::Observer, RoleName::Router];
    for id in device_ids {
        let role = RoleName::Device(id.clone());
        role.check().map_err(anyhow::Error::msg)?;
        names.push(role);
    }
    let mut sans = vec![
        "localhost".to_owned(),
        "127.0.0.1".to_owned(),
        "::1".to_owned(),
    ];
    for host in hosts {
        anyhow::ensure!(
            !host.is_empty()
                && host
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || ".-:".contains(c)),
            "--host `{host}`: expected a DNS name or an IP address"
        );
        sans.push(host.clone());
    }

    let ca_key = KeyPair::generate().context("generating the CA key")?;
    let mut ca_params = CertificateParams::new(Vec::<String>::new()).context("CA parameters")?;
    ca_params.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
    ca_params
        .distinguished_name
        .push(DnType::CommonName, "sinew lab CA");
    ca_params.key_usages = vec![
        KeyUsagePurpose::KeyCertSign,
        KeyUsagePurpose::DigitalSignature,
        KeyUsagePurpose::CrlSign,
    ];
    let ca_cert = ca_params.self_signed(&ca_key).context("signing the CA")?;
    let ca_path = dir.join("ca.pem");
    std::fs::write(&ca_path, ca_cert.pem())
        .with_context(|| format!("writing {}", ca_path.display()))?;
    write_private(&ca_key_path, &ca_key.serialize_pem())?;
    let issuer = Issuer::new(ca_params, ca_key);

    let mut roles = Vec::new();
    for role in names {
        let name = role.common_name();
        let key = KeyPair::generate().with_context(|| format!("generating the key of {name}"))?;
        let mut params = CertificateParams::new(sans.clone())
            .with_context(|| format!("parameters of {name}"))?;
        params
            .distinguished_name
            .push(DnType::CommonName, name.clone());
        params.extended_key_usages = vec![
            ExtendedKeyUsagePurpose::ServerAuth,
            ExtendedKeyUsagePurpose::ClientAuth,
        ];
        let cert = params
            .signed_by(&key, &issuer)
            .with_context(|| format!("signing {name}"))?;
        let cert_path = dir.join(format!("{name}.pem"));
        let key_path = dir.join(format!("{name}-key.pem"));
        std::fs::write(&cert_path, cert.pem())
            .with_context(|| format!("writing {}", cert_path.display()))?;
        write_private(&key_path, &key.serialize_pem())?;
        roles.push((
            name,
            TlsFiles {
                ca: ca_path.clone(),
                cert: cert_path,
                key: key_path,
            },
        ));
    }
    Ok(LabCerts {
        dir: dir.to_owned(),
        ca: ca_path,
        roles,
    })
}

/// Write `zenohd.json5` into the lab's folder: `zenohd -c` it to run the site's router (listening on `listen`,
/// QUIC endpoints; mutual TLS with the lab's `router` certificate; the lab's access rules for `scene` and its
/// devices `device_ids`). Returns its path.
pub fn write_router_config(
    certs: &LabCerts,
    listen: &[String],
    scene: &str,
    device_ids: &[String],
) -> anyhow::Result<PathBuf> {
    let router = certs
        .role(&RoleName::Router.common_name())
        .context("the lab has no router certificate")?;
    sinew_protocol::keys::validate_segment("scene", scene).map_err(|e| anyhow::anyhow!("{e}"))?;
    let text =
        sinew_protocol::zenoh_config_file::lab_router_config(listen, router, scene, device_ids);
    let path = certs.dir.join("zenohd.json5");
    let header = format!(
        "// The {scene} lab's zenoh router: `zenohd -c {}`. Every role connects to it in client mode\n\
         // (`--zenoh-mode client --connect quic/<router>:<port>` with its own --tls-* files); it enforces the\n\
         // lab's access rules on what each client brings in. Written by `sinew certs`.\n",
        path.display()
    );
    std::fs::write(&path, header + &text).with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}
