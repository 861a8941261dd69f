//! The contract's own checks: its shape, its roles, and docs/api.md against it.

use super::*;
use serde_json::Value;

fn spec() -> Value {
    serde_json::from_str(document()).unwrap()
}

#[test]
fn the_document_is_openapi_3_1_and_every_reference_resolves() {
    let v = spec();
    assert!(
        v["openapi"].as_str().unwrap().starts_with("3.1"),
        "{}",
        v["openapi"]
    );
    let text = document();
    for part in text.split("\"$ref\":\"#/components/schemas/").skip(1) {
        let name = part.split('"').next().unwrap();
        assert!(
            v["components"]["schemas"][name].is_object(),
            "schema {name} referred to but missing"
        );
    }
    assert_eq!(
        v["components"]["securitySchemes"]["bearer"]["scheme"],
        "bearer"
    );
}

#[test]
fn every_operation_has_a_role_an_id_and_described_answers() {
    let doc = contract();
    let mut ids = Vec::new();
    for (method, path, op) in operations(doc) {
        let access = access_of(op).unwrap_or_else(|| panic!("{method} {path}: no role"));
        let id = op.operation_id.clone().unwrap();
        assert!(!ids.contains(&id), "operation id {id} twice");
        ids.push(id);
        let statuses: Vec<&str> = op.responses.responses.keys().map(String::as_str).collect();
        if access != Access::Public {
            for s in ["401", "403", "429"] {
                assert!(statuses.contains(&s), "{method} {path}: no {s}");
            }
        }
        if method != "GET" {
            assert!(
                statuses.contains(&"409"),
                "{method} {path}: no 409 (standby)"
            );
        }
        let v = serde_json::to_value(op).unwrap();
        for (status, r) in v["responses"].as_object().unwrap() {
            assert!(
                !r["description"].as_str().unwrap_or("").is_empty(),
                "{method} {path} {status}: no description"
            );
            if status.starts_with('4') || status.starts_with('5') {
                assert_eq!(
                    r["content"]["application/json"]["schema"]["$ref"],
                    "#/components/schemas/ErrorBody",
                    "{method} {path} {status}"
                );
            }
        }
    }
    assert!(ids.len() > 40, "{ids:?}");
}

#[test]
fn only_health_and_the_contract_are_public() {
    let public: Vec<(&str, &str)> = operations(contract())
        .filter(|(_, _, op)| access_of(op) == Some(Access::Public))
        .map(|(m, p, _)| (m, p))
        .collect();
    assert_eq!(
        public,
        [("GET", "/api/v1/health"), ("GET", "/api/v1/openapi.json")]
    );
}

/// The properties of an operation's JSON request body schema (following one `$ref`).
fn body_properties(v: &Value, op: &Value) -> Vec<String> {
    let schema = &op["requestBody"]["content"]["application/json"]["schema"];
    let schema = match schema["$ref"].as_str() {
        Some(r) => &v["components"]["schemas"][r.rsplit('/').next().unwrap()],
        None => schema,
    };
    let mut names: Vec<String> = Vec::new();
    let mut add = |s: &Value| {
        if let Some(p) = s["properties"].as_object() {
            names.extend(p.keys().cloned());
        }
    };
    add(schema);
    for variant in schema["oneOf"].as_array().into_iter().flatten() {
        add(variant);
    }
    names
}

#[test]
fn swarm_checks_name_fields_of_the_body() {
    let v = spec();
    let mut checked = 0;
    for (path, item) in v["paths"].as_object().unwrap() {
        for (method, op) in item.as_object().unwrap() {
            let Some(fields) = op[SWARM_CHECKS_EXTENSION].as_object() else {
                continue;
            };
            checked += 1;
            let properties = body_properties(&v, op);
            for field in fields.keys() {
                assert!(
                    field == "body" || properties.contains(field),
                    "{method} {path}: {SWARM_CHECKS_EXTENSION} names `{field}`, not a field of \
                     its body ({properties:?})"
                );
            }
        }
    }
    assert!(checked >= 5, "{checked}");
}

/// The (method, path, role) rows of the first table of docs/api.md.
fn documented() -> Vec<(String, String, String)> {
    let text =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/api.md")).unwrap();
    let table = text
        .lines()
        .skip_while(|l| !l.starts_with("| method | path | role |"))
        .skip(2)
        .take_while(|l| l.starts_with('|'));
    table
        .map(|line| {
            let cells: Vec<&str> = line.split('|').map(str::trim).collect();
            (
                cells[1].to_string(),
                cells[2].trim_matches('`').to_string(),
                cells[3].to_string(),
            )
        })
        .collect()
}

#[test]
fn docs_api_md_lists_every_operation_with_its_role_and_nothing_else() {
    let docs = documented();
    assert!(docs.len() > 40, "{docs:?}");
    let table = super::route_access();
    for (m, p, role) in &docs {
        let found = table.iter().find(|r| r.method == *m && r.path == *p);
        let Some(r) = found else {
            panic!("docs/api.md lists {m} {p}, which the contract has not");
        };
        assert_eq!(
            r.access.as_str(),
            role,
            "docs/api.md gives {m} {p} the role {role}, the contract {}",
            r.access.as_str()
        );
    }
    for r in table {
        assert!(
            docs.iter().any(|(m, p, _)| *m == r.method && *p == r.path),
            "the contract has {} {}, which docs/api.md does not list",
            r.method,
            r.path
        );
    }
}
#[test]
fn dump() {
    std::fs::write("/tmp/openapi.json", document()).unwrap();
}

#[test]
fn the_role_table_has_every_operation_once_with_its_role() {
    let table = super::route_access();
    let role = |m: &str, p: &str| {
        table
            .iter()
            .find(|r| r.method == m && r.path == p)
            .map(|r| r.access)
    };
    assert_eq!(role("GET", "/api/v1/health"), Some(Access::Public));
    assert_eq!(
        role("GET", "/api/v1/vehicles"),
        Some(Access::Role(Role::Viewer))
    );
    assert_eq!(
        role("POST", "/api/v1/formation/leader/orbit"),
        Some(Access::Role(Role::Operator))
    );
    assert_eq!(
        role("PUT", "/api/v1/vehicles/{id}/params/{name}"),
        Some(Access::Role(Role::Admin))
    );
    assert_eq!(role("POST", "/api/v1/plugins/{op}"), None);
    for (i, r) in table.iter().enumerate() {
        assert!(
            !table[..i]
                .iter()
                .any(|o| o.method == r.method && o.path == r.path),
            "{} {} twice",
            r.method,
            r.path
        );
    }
}
