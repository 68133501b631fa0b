//! `sinew certs`: the certificates a lab needs to run sessions only the invited can join.
//!
//! Owns: the lab's certificate authority (made once, reused for each scene added), one certificate per role of
//! a scene, signed by it, as PEM files, the site's router certificate, and the lab's `zenohd` configuration
//! ([`write_router_config`]). Layout: `<lab>/ca.pem`, `ca-key.pem`, `router.pem`, `zenohd.json5`, and per scene
//! `<lab>/<scene>/server.pem`, `observer.pem`, `device-<id>.pem` (each with its `-key.pem`). A certificate's
//! common name says the role and its scene (`server@pad`, `device-left@pad`; the router's is `router`), which
//! zenoh's access control matches (see `sinew_protocol::security`); every certificate names the hosts it may be
//! reached at (localhost and the loopback addresses, plus `--host`), because in peer mode each role both
//! accepts and dials, so each certificate serves as a TLS server and a TLS client.
//!
//! Must not: replace an existing CA (a lab that loses it must re-issue every certificate), re-issue a scene's
//! certificates over its own, or write a private key readable by others.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::Context;
use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};
use sinew_protocol::security::{RoleName, SceneRoles, TlsFiles};

/// What [`make_lab_certs`] wrote (or found) for one scene.
#[derive(Debug, Clone, PartialEq)]
pub struct LabCerts {
    /// The lab's folder.
    pub dir: PathBuf,
    /// The CA certificate every role trusts.
    pub ca: PathBuf,
    /// The scene these roles are for.
    pub scene: String,
    /// Per role: its short name (`server`, `observer`, `device-<id>`, `router`: the file's stem) and files. Its
    /// certificate's common name is [`RoleName::common_name`] in the scene.
    pub roles: Vec<(String, TlsFiles)>,
}

impl LabCerts {
    /// The files of the role with short name `name` (`server`, `observer`, `device-left`, `router`).
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

fn read(path: &Path) -> anyhow::Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))
}

/// The lab's CA: the one in `dir` if it has one (`ca.pem` and `ca-key.pem`: a lab adds a scene with the CA it
/// has), else a new one written there.
fn lab_ca(dir: &Path) -> anyhow::Result<(PathBuf, Issuer<'static, KeyPair>)> {
    let ca_path = dir.join("ca.pem");
    let ca_key_path = dir.join("ca-key.pem");
    if ca_key_path.exists() {
        let key = KeyPair::from_pem(&read(&ca_key_path)?)
            .with_context(|| format!("{}: not a private key", ca_key_path.display()))?;
        let issuer = Issuer::from_ca_cert_pem(&read(&ca_path)?, key)
            .with_context(|| format!("{}: not a CA certificate", ca_path.display()))?;
        return Ok((ca_path, issuer));
    }
    anyhow::ensure!(
        !ca_path.exists(),
        "{} exists without its key ca-key.pem: a new CA would orphan every certificate it signed (restore the \
         key, or use another --out)",
        ca_path.display()
    );
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
    std::fs::write(&ca_path, ca_cert.pem())
        .with_context(|| format!("writing {}", ca_path.display()))?;
    write_private(&ca_key_path, &ca_key.serialize_pem())?;
    Ok((ca_path, Issuer::new(ca_params, ca_key)))
}

/// Issue one role's certificate (common name `common_name`, reachable at `sans`) into `folder` as
/// `<stem>.pem` and `<stem>-key.pem`.
fn issue(
    issuer: &Issuer<'static, KeyPair>,
    ca: &Path,
    folder: &Path,
    stem: &str,
    common_name: &str,
    sans: &[String],
) -> anyhow::Result<TlsFiles> {
    let key =
        KeyPair::generate().with_context(|| format!("generating the key of {common_name}"))?;
    let mut params = CertificateParams::new(sans.to_vec())
        .with_context(|| format!("parameters of {common_name}"))?;
    params
        .distinguished_name
        .push(DnType::CommonName, common_name.to_owned());
    params.extended_key_usages = vec![
        ExtendedKeyUsagePurpose::ServerAuth,
        ExtendedKeyUsagePurpose::ClientAuth,
    ];
    let cert = params
        .signed_by(&key, issuer)
        .with_context(|| format!("signing {common_name}"))?;
    let cert_path = folder.join(format!("{stem}.pem"));
    let key_path = folder.join(format!("{stem}-key.pem"));
    std::fs::write(&cert_path, cert.pem())
        .with_context(|| format!("writing {}", cert_path.display()))?;
    write_private(&key_path, &key.serialize_pem())?;
    Ok(TlsFiles {
        ca: ca.to_owned(),
        cert: cert_path,
        key: key_path,
    })
}

/// Make the certificates of `scene` in the lab at `dir` (created if needed): the server, one observer and each
/// device in `device_ids`, into `dir/<scene>/`, signed by the lab's CA (`dir/ca.pem`; made if the lab has none,
/// reused if it has), and the site's router certificate (`dir/router.pem`; made once, for every scene). `hosts`
/// are extra names or addresses the roles are reached at (a site's DNS name). Refuses to re-issue a scene the
/// lab already has, and never replaces the CA.
pub fn make_lab_certs(
    dir: &Path,
    scene: &str,
    device_ids: &[String],
    hosts: &[String],
) -> anyhow::Result<LabCerts> {
    sinew_protocol::keys::validate_segment("scene", scene).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut names: Vec<RoleName> = vec![RoleName::Server, RoleName::Observer];
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
    let scene_dir = dir.join(scene);
    anyhow::ensure!(
        !scene_dir.join("server.pem").exists(),
        "{} already holds scene `{scene}`'s certificates: refusing to re-issue them (remove the folder to \
         re-issue every role of the scene)",
        scene_dir.display()
    );
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let (ca_path, issuer) = lab_ca(dir)?;
    std::fs::create_dir_all(&scene_dir)
        .with_context(|| format!("creating {}", scene_dir.display()))?;

    let mut roles = Vec::new();
    let router_stem = RoleName::Router.common_name(scene);
    let router = if dir.join(format!("{router_stem}.pem")).exists() {
        TlsFiles {
            ca: ca_path.clone(),
            cert: dir.join(format!("{router_stem}.pem")),
            key: dir.join(format!("{router_stem}-key.pem")),
        }
    } else {
        issue(&issuer, &ca_path, dir, &router_stem, &router_stem, &sans)?
    };
    roles.push((router_stem, router));
    for role in names {
        let stem = role.common_name(scene);
        let stem = stem
            .strip_suffix(&format!("@{scene}"))
            .unwrap_or(&stem)
            .to_owned();
        let files = issue(
            &issuer,
            &ca_path,
            &scene_dir,
            &stem,
            &role.common_name(scene),
            &sans,
        )?;
        roles.push((stem, files));
    }
    Ok(LabCerts {
        dir: dir.to_owned(),
        ca: ca_path,
        scene: scene.to_owned(),
        roles,
    })
}

/// The scenes the lab at `dir` holds certificates for (each folder with a `server.pem`), with their devices
/// (each `device-<id>.pem` in it), in name order.
pub fn lab_scenes(dir: &Path) -> anyhow::Result<Vec<SceneRoles>> {
    let mut scenes = Vec::new();
    for entry in std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))? {
        let folder = entry
            .with_context(|| format!("reading {}", dir.display()))?
            .path();
        if !folder.join("server.pem").is_file() {
            continue;
        }
        let Some(scene) = folder.file_name().and_then(|n| n.to_str()) else {
            continue;
        };
        let mut device_ids = Vec::new();
        for file in
            std::fs::read_dir(&folder).with_context(|| format!("reading {}", folder.display()))?
        {
            let file = file.with_context(|| format!("reading {}", folder.display()))?;
            let name = file.file_name();
            let Some(id) = name
                .to_str()
                .and_then(|n| n.strip_prefix("device-"))
                .and_then(|n| n.strip_suffix(".pem"))
            else {
                continue;
            };
            if !id.ends_with("-key") {
                device_ids.push(id.to_owned());
            }
        }
        device_ids.sort();
        scenes.push(SceneRoles {
            scene: scene.to_owned(),
            device_ids,
        });
    }
    scenes.sort_by(|a, b| a.scene.cmp(&b.scene));
    Ok(scenes)
}

/// Write `zenohd.json5` into the lab's folder `dir`: `zenohd -c` it to run the site's router (listening on
/// `listen`, QUIC endpoints; mutual TLS with the lab's `router` certificate; the access rules of every scene the
/// lab holds, [`lab_scenes`]). Rewrite it after adding a scene. Returns its path.
pub fn write_router_config(dir: &Path, listen: &[String]) -> anyhow::Result<PathBuf> {
    let router = TlsFiles {
        ca: dir.join("ca.pem"),
        cert: dir.join("router.pem"),
        key: dir.join("router-key.pem"),
    };
    router
        .check()
        .map_err(|e| anyhow::anyhow!("the lab has no router certificate: {e}"))?;
    let scenes = lab_scenes(dir)?;
    anyhow::ensure!(
        !scenes.is_empty(),
        "{} holds no scene's certificates (`sinew certs --scene NAME`)",
        dir.display()
    );
    let text = sinew_protocol::zenoh_config_file::lab_router_config(listen, &router, &scenes);
    let path = dir.join("zenohd.json5");
    let names: Vec<&str> = scenes.iter().map(|s| s.scene.as_str()).collect();
    let header = format!(
        "// The lab's zenoh router, for the scenes {}: `zenohd -c {}`. Every role connects to it in client\n\
         // mode (`--zenoh-mode client --connect quic/<router>:<port>` with its own --tls-* files); it holds each\n\
         // to its scene's access rules. Written by `sinew certs`.\n",
        names.join(", "),
        path.display()
    );
    std::fs::write(&path, header + &text).with_context(|| format!("writing {}", path.display()))?;
    Ok(path)
}
