//! Parameters that describe themselves: name, doc, unit, type, default and valid range, so the
//! host can print a kind's parameters and validate a scene before any plugin code runs.
//!
//! Parameters travel as a JSON object. [`validate`] checks every key against the kind's
//! [`ParamInfo`]s (unknown names, types, ranges — each error names the parameter) and fills
//! in defaults; [`parse`] then deserializes the completed object into the plugin's own serde
//! struct.

use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::{Map, Value};

use crate::abi::{ParamInfo, ParamType, PluginError};

/// Builder for a [`ParamInfo`].
#[derive(Debug, Clone)]
pub struct ParamSpec {
    info: ParamInfo,
}

impl ParamSpec {
    fn new(name: &str, ty: ParamType, default: Value) -> Self {
        Self {
            info: ParamInfo {
                name: name.into(),
                doc: "".into(),
                unit: "".into(),
                ty,
                default: default.to_string().into(),
                min: f64::NEG_INFINITY,
                max: f64::INFINITY,
            },
        }
    }
    /// A real-valued parameter.
    pub fn number(name: &str, default: f64) -> Self {
        Self::new(name, ParamType::NUMBER, Value::from(default))
    }
    /// An integer parameter.
    pub fn integer(name: &str, default: i64) -> Self {
        Self::new(name, ParamType::INTEGER, Value::from(default))
    }
    /// A boolean parameter.
    pub fn boolean(name: &str, default: bool) -> Self {
        Self::new(name, ParamType::BOOL, Value::from(default))
    }
    /// A 3-vector parameter.
    pub fn vec3(name: &str, default: [f64; 3]) -> Self {
        Self::new(name, ParamType::VEC3, Value::from(default.to_vec()))
    }
    /// A text parameter.
    pub fn text(name: &str, default: &str) -> Self {
        Self::new(name, ParamType::TEXT, Value::from(default))
    }
    /// A free-form parameter (table or list) the plugin validates itself.
    pub fn any(name: &str, default: Value) -> Self {
        Self::new(name, ParamType::ANY, default)
    }
    /// Sets the one-line doc.
    pub fn doc(mut self, doc: &str) -> Self {
        self.info.doc = doc.into();
        self
    }
    /// Sets the unit.
    pub fn unit(mut self, unit: &str) -> Self {
        self.info.unit = unit.into();
        self
    }
    /// Sets the valid range (inclusive) of a number or integer.
    pub fn range(mut self, min: f64, max: f64) -> Self {
        self.info.min = min;
        self.info.max = max;
        self
    }
    /// The ABI description.
    pub fn info(&self) -> ParamInfo {
        self.info.clone()
    }
}

/// Checks one value against its description.
fn check_value(value: &Value, info: &ParamInfo) -> Result<(), String> {
    let number_in_range = |x: f64| -> Result<(), String> {
        if !x.is_finite() {
            return Err("must be finite".into());
        }
        if x < info.min || x > info.max {
            return Err(format!(
                "{x} is outside the valid range [{}, {}]",
                info.min, info.max
            ));
        }
        Ok(())
    };
    match info.ty {
        ParamType::NUMBER => match value.as_f64() {
            Some(x) => number_in_range(x),
            None => Err(format!("expected a number, found {value}")),
        },
        ParamType::INTEGER => match value.as_i64() {
            Some(i) => number_in_range(i as f64),
            None => Err(format!("expected an integer, found {value}")),
        },
        ParamType::BOOL => match value {
            Value::Bool(_) => Ok(()),
            _ => Err(format!("expected true or false, found {value}")),
        },
        ParamType::VEC3 => match value.as_array() {
            Some(a) if a.len() == 3 && a.iter().all(|c| c.as_f64().is_some_and(f64::is_finite)) => {
                Ok(())
            }
            _ => Err(format!(
                "expected [x, y, z] of finite numbers, found {value}"
            )),
        },
        ParamType::TEXT => match value {
            Value::String(_) => Ok(()),
            _ => Err(format!("expected a string, found {value}")),
        },
        _ => Ok(()),
    }
}

/// Validates a parameter object against the descriptions and fills in defaults.
///
/// Errors name the parameter: unknown names (with the list of known ones), wrong types and
/// values outside the valid range.
pub fn validate(value: &Value, infos: &[ParamInfo]) -> Result<Map<String, Value>, PluginError> {
    let empty = Map::new();
    let given = match value {
        Value::Object(m) => m,
        Value::Null => &empty,
        other => {
            return Err(PluginError::bad_parameter(
                "",
                format!("parameters must be a table, found {other}"),
            ))
        }
    };
    for (name, v) in given {
        let Some(info) = infos.iter().find(|i| i.name.as_str() == name) else {
            let known: Vec<&str> = infos.iter().map(|i| i.name.as_str()).collect();
            return Err(PluginError::bad_parameter(
                name.as_str(),
                format!("unknown parameter; known: {}", known.join(", ")),
            ));
        };
        check_value(v, info).map_err(|m| PluginError::bad_parameter(name.as_str(), m))?;
    }
    let mut out = Map::new();
    for info in infos {
        let v = match given.get(info.name.as_str()) {
            Some(v) => v.clone(),
            None => serde_json::from_str(info.default.as_str()).map_err(|e| {
                PluginError::bad_parameter(info.name.as_str(), format!("bad default: {e}"))
            })?,
        };
        out.insert(info.name.to_string(), v);
    }
    Ok(out)
}

/// [`validate`] on JSON text, returning the completed object as JSON text.
pub fn validate_json(json: &str, infos: &[ParamInfo]) -> Result<String, PluginError> {
    let value: Value = if json.trim().is_empty() {
        Value::Null
    } else {
        serde_json::from_str(json)
            .map_err(|e| PluginError::bad_parameter("", format!("not valid JSON: {e}")))?
    };
    Ok(Value::Object(validate(&value, infos)?).to_string())
}

/// Checks a plugin's own parameter struct against its descriptions (the [`validate`] a
/// group's constructor runs on parameters built in code rather than parsed from a scene);
/// an error names the parameter.
///
/// ```
/// use nucleus_sdk::params::{validate_against, ParamSpec};
/// #[derive(serde::Serialize)]
/// struct Params { stiffness: f64 }
/// let specs = [ParamSpec::number("stiffness", 1.0).range(0.0, 1.0)];
/// assert!(validate_against(&Params { stiffness: 0.5 }, &specs).is_ok());
/// let e = validate_against(&Params { stiffness: 2.0 }, &specs).unwrap_err();
/// assert_eq!(e.subject.as_str(), "stiffness");
/// ```
pub fn validate_against<T: Serialize>(params: &T, specs: &[ParamSpec]) -> Result<(), PluginError> {
    let infos: Vec<_> = specs.iter().map(ParamSpec::info).collect();
    let value = serde_json::to_value(params)
        .map_err(|e| PluginError::failed(format!("cannot serialize parameters: {e}")))?;
    validate(&value, &infos).map(|_| ())
}

/// Deserializes validated parameters into the plugin's own struct. A failure names the
/// parameter where serde says which one it is.
pub fn parse<T: DeserializeOwned>(json: &str) -> Result<T, PluginError> {
    serde_json::from_str(json).map_err(|e| {
        let msg = e.to_string();
        let subject = msg
            .split('`')
            .nth(1)
            .filter(|_| msg.contains("field"))
            .unwrap_or("")
            .to_string();
        PluginError::bad_parameter(subject, msg)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn specs() -> Vec<ParamInfo> {
        vec![
            ParamSpec::number("compliance", 0.0)
                .range(0.0, f64::INFINITY)
                .info(),
            ParamSpec::boolean("enabled", true).info(),
            ParamSpec::vec3("direction", [1.0, 0.0, 0.0]).info(),
        ]
    }

    #[test]
    fn defaults_fill_missing_parameters() {
        let m = validate(&json!({"compliance": 1e-6}), &specs()).unwrap();
        assert_eq!(m["compliance"], json!(1e-6));
        assert_eq!(m["enabled"], json!(true));
        assert_eq!(m["direction"], json!([1.0, 0.0, 0.0]));
    }

    #[test]
    fn unknown_parameter_is_named() {
        let e = validate(&json!({"complience": 1.0}), &specs()).unwrap_err();
        assert_eq!(e.code, PluginError::BAD_PARAMETER);
        assert_eq!(e.subject.as_str(), "complience");
        assert!(e.message.contains("compliance"), "{e}");
    }

    #[test]
    fn out_of_range_and_wrong_type_are_named() {
        let e = validate(&json!({"compliance": -1.0}), &specs()).unwrap_err();
        assert_eq!(e.subject.as_str(), "compliance");
        let e = validate(&json!({"enabled": 3}), &specs()).unwrap_err();
        assert_eq!(e.subject.as_str(), "enabled");
        let e = validate(&json!({"direction": [1, 2]}), &specs()).unwrap_err();
        assert_eq!(e.subject.as_str(), "direction");
    }

    #[test]
    fn parse_names_the_field() {
        #[derive(serde::Deserialize, Debug)]
        #[serde(deny_unknown_fields)]
        #[allow(dead_code)]
        struct P {
            compliance: f64,
        }
        let e = parse::<P>(r#"{"compliance": 1.0, "bogus": 2}"#).unwrap_err();
        assert_eq!(e.subject.as_str(), "bogus");
    }
}
