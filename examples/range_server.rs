//! A static HTTP/1.1 file server answering `Range` requests (keep-alive), for measuring
//! streaming over HTTP on loopback (`python3 -m http.server` ignores ranges):
//!
//!     cargo run --release --example range_server -- DIR PORT

use std::io::{BufRead, BufReader, Read, Seek, SeekFrom, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};

fn answer(root: &Path, stream: TcpStream) -> std::io::Result<()> {
    let mut reader = BufReader::new(stream.try_clone()?);
    stream.set_nodelay(true)?;
    let mut out = stream;
    loop {
        let mut line = String::new();
        if reader.read_line(&mut line)? == 0 {
            return Ok(());
        }
        let path = line.split_whitespace().nth(1).unwrap_or("/").to_owned();
        let mut range = None;
        loop {
            let mut h = String::new();
            if reader.read_line(&mut h)? == 0 || h.trim().is_empty() {
                break;
            }
            if let Some(r) = h.to_ascii_lowercase().strip_prefix("range: bytes=") {
                if let Some((a, b)) = r.trim().split_once('-') {
                    range = a.parse::<u64>().ok().zip(b.parse::<u64>().ok());
                }
            }
        }
        let file = root.join(path.trim_start_matches('/'));
        let Ok(mut f) = std::fs::File::open(&file) else {
            out.write_all(b"HTTP/1.1 404 Not Found\r\nContent-Length: 0\r\n\r\n")?;
            continue;
        };
        let size = f.metadata()?.len();
        let (a, b, status) = match range {
            Some((a, b)) if a < size => (a, b.min(size - 1), "206 Partial Content"),
            Some(_) => {
                out.write_all(b"HTTP/1.1 416 Range Not Satisfiable\r\nContent-Length: 0\r\n\r\n")?;
                continue;
            }
            None => (0, size.saturating_sub(1), "200 OK"),
        };
        let mut body = vec![0; (b + 1 - a) as usize];
        f.seek(SeekFrom::Start(a))?;
        f.read_exact(&mut body)?;
        let head = format!(
            "HTTP/1.1 {status}\r\nContent-Length: {}\r\nContent-Range: bytes {a}-{b}/{size}\r\n\r\n",
            body.len()
        );
        out.write_all(head.as_bytes())?;
        out.write_all(&body)?;
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (Some(dir), Some(port)) = (args.get(1), args.get(2)) else {
        eprintln!("usage: range_server DIR PORT");
        std::process::exit(2);
    };
    let root = PathBuf::from(dir);
    let listener = TcpListener::bind(format!("127.0.0.1:{port}")).expect("bind");
    for stream in listener.incoming().flatten() {
        let root = root.clone();
        std::thread::spawn(move || {
            // A client that hangs up ends its connection's thread.
            let _ = answer(&root, stream);
        });
    }
}
