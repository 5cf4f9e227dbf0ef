//! rpclib's msgpack-RPC as CARLA 0.9.16 uses it: requests
//! `[0, id, method, [[async], args...]]`, responses `[1, id, nil, result]`,
//! results wrapped as CARLA's `Response<T>` (`[[1, value]]`, errors
//! `[[0, [message]]]`; `Response<void>`: `[[false]]`, `[[true, [message]]]`).

use std::io::Read;

use rmpv::Value;

/// The largest request accepted; a longer one drops the connection.
pub(crate) const MAX_REQUEST_BYTES: usize = 16 << 20;
/// The deepest nesting accepted (CARLA's deepest, a batch command with a
/// `.then(...)`, is about 12); deeper drops the connection instead of
/// recursing the decoder and the gateway's stack away.
pub(crate) const MAX_DEPTH: usize = 48;

/// One request.
#[derive(Debug)]
pub(crate) struct Request {
    pub(crate) id: Value,
    pub(crate) method: String,
    /// The client does not wait for the answer (CARLA's async calls).
    pub(crate) asynchronous: bool,
    pub(crate) args: Vec<Value>,
}

/// Why reading a request failed: the connection is dropped.
#[derive(Debug, thiserror::Error)]
pub(crate) enum ReadError {
    #[error("connection closed")]
    Closed,
    #[error("not msgpack: {0}")]
    Garbage(#[source] rmpv::decode::Error),
    #[error("a request longer than {MAX_REQUEST_BYTES} bytes")]
    TooLong,
    #[error("not a msgpack-RPC request: {0}")]
    NotRequest(&'static str),
}

/// A reader that fails past `left` bytes (reset for each request).
struct Limited<'a, R> {
    inner: &'a mut R,
    left: usize,
    read: usize,
}

impl<R: Read> Read for Limited<'_, R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.left == 0 {
            return Err(std::io::Error::other("request too long"));
        }
        let n = buf.len().min(self.left);
        let got = self.inner.read(&mut buf[..n])?;
        self.left -= got;
        self.read += got;
        Ok(got)
    }
}

/// Reads the next request from `reader`: CARLA's, whose first parameter
/// is its call metadata.
pub(crate) fn read_request<R: Read>(reader: &mut R) -> Result<Request, ReadError> {
    let mut request = read_plain_request(reader)?;
    // CARLA's first parameter is its call metadata: [asynchronous].
    if let Some(Value::Array(meta)) = request.args.first() {
        request.asynchronous = meta.first().and_then(Value::as_bool).unwrap_or(false);
        request.args.remove(0);
    }
    Ok(request)
}

/// Reads the next request from `reader` as plain rpclib sends it (CARLA's
/// traffic manager protocol: no metadata; every call is waited for).
pub(crate) fn read_plain_request<R: Read>(reader: &mut R) -> Result<Request, ReadError> {
    let mut limited = Limited {
        inner: reader,
        left: MAX_REQUEST_BYTES,
        read: 0,
    };
    let value = match rmpv::decode::read_value_with_max_depth(&mut limited, MAX_DEPTH) {
        Ok(value) => value,
        Err(_) if limited.read == 0 => return Err(ReadError::Closed),
        Err(_) if limited.left == 0 => return Err(ReadError::TooLong),
        Err(e) => return Err(ReadError::Garbage(e)),
    };
    let Value::Array(mut parts) = value else {
        return Err(ReadError::NotRequest("not an array"));
    };
    if parts.len() != 4 || parts[0].as_u64() != Some(0) {
        return Err(ReadError::NotRequest("not [0, id, method, params]"));
    }
    let params = parts.pop().unwrap_or(Value::Nil);
    let method = parts.pop().unwrap_or(Value::Nil);
    let id = parts.pop().unwrap_or(Value::Nil);
    let Some(method) = method.as_str().map(str::to_string) else {
        return Err(ReadError::NotRequest("the method is not a string"));
    };
    let Value::Array(args) = params else {
        return Err(ReadError::NotRequest("the params are not an array"));
    };
    Ok(Request {
        id,
        method,
        asynchronous: false,
        args,
    })
}

/// What a method answers.
#[derive(Debug)]
pub(crate) enum Answer {
    /// `Response<T>` with a value.
    Value(Value),
    /// `Response<void>` done.
    Done,
    /// A result not wrapped in `Response<T>` (`apply_batch`'s list).
    Raw(Value),
    /// An error the client raises as `RuntimeError(message)`; `void` says
    /// whether the method is a `Response<void>` one.
    Error { message: String, void: bool },
    /// An rpclib error (for unwrapped results; the client raises
    /// `RuntimeError` naming the method, without the message).
    RpcError(String),
}

/// The response message for request `id`.
pub(crate) fn response(id: Value, answer: Answer) -> Vec<u8> {
    let error = |m: String| Value::Array(vec![Value::from(m)]);
    let mut failure = Value::Nil;
    let result = match answer {
        Answer::Raw(v) => v,
        Answer::RpcError(message) => {
            failure = Value::from(message);
            Value::Nil
        }
        Answer::Value(v) => Value::Array(vec![Value::Array(vec![Value::from(1), v])]),
        Answer::Done => Value::Array(vec![Value::Array(vec![Value::Boolean(false)])]),
        Answer::Error {
            message,
            void: false,
        } => Value::Array(vec![Value::Array(vec![Value::from(0), error(message)])]),
        Answer::Error {
            message,
            void: true,
        } => Value::Array(vec![Value::Array(vec![
            Value::Boolean(true),
            error(message),
        ])]),
    };
    let message = Value::Array(vec![Value::from(1), id, failure, result]);
    let mut out = Vec::new();
    // Encoding into a Vec cannot fail.
    let _ = rmpv::encode::write_value(&mut out, &message);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn encode(v: &Value) -> Vec<u8> {
        let mut out = Vec::new();
        rmpv::encode::write_value(&mut out, v).unwrap();
        out
    }

    #[test]
    fn requests_and_responses_have_carlas_shape() {
        // `version` as the 0.9.16 client sends it.
        let bytes = [
            0x94, 0x00, 0x01, 0xa7, b'v', b'e', b'r', b's', b'i', b'o', b'n', 0x91, 0x91, 0xc2,
        ];
        let request = read_request(&mut &bytes[..]).unwrap();
        assert_eq!(
            (
                request.method.as_str(),
                request.asynchronous,
                request.args.len()
            ),
            ("version", false, 0)
        );
        let out = response(request.id, Answer::Value(Value::from("0.9.16")));
        assert_eq!(
            out,
            [
                &[0x94, 0x01, 0x01, 0xc0, 0x91, 0x92, 0x01, 0xa6][..],
                b"0.9.16"
            ]
            .concat()
        );
        let void = response(Value::from(7), Answer::Done);
        assert_eq!(void, [0x94, 0x01, 0x07, 0xc0, 0x91, 0x91, 0xc2]);
    }

    #[test]
    fn garbage_and_wrong_shapes_are_errors() {
        assert!(matches!(read_request(&mut &[][..]), Err(ReadError::Closed)));
        let truncated = [0x93u8, 0x01];
        assert!(matches!(
            read_request(&mut &truncated[..]),
            Err(ReadError::Garbage(_))
        ));
        let not_request = encode(&Value::Array(vec![Value::from(2), Value::from("x")]));
        assert!(matches!(
            read_request(&mut &not_request[..]),
            Err(ReadError::NotRequest(_))
        ));
        // Nesting past the limit.
        let mut deep = Value::Nil;
        for _ in 0..MAX_DEPTH + 1 {
            deep = Value::Array(vec![deep]);
        }
        let deep = encode(&Value::Array(vec![
            Value::from(0),
            Value::from(1),
            Value::from("apply_batch"),
            deep,
        ]));
        assert!(matches!(
            read_request(&mut &deep[..]),
            Err(ReadError::Garbage(_))
        ));
        // A 20 MiB string.
        let mut long = vec![0xdb];
        long.extend_from_slice(&(20u32 << 20).to_be_bytes());
        long.resize(long.len() + (20 << 20), b'x');
        assert!(matches!(
            read_request(&mut &long[..]),
            Err(ReadError::TooLong)
        ));
    }
}
