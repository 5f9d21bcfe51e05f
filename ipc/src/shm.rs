//! Where a byte lives in shared memory: (file, offset) from
//! `/proc/self/maps`. Two processes that find a frame's pixels at the same
//! file and offset read the same physical pages: the frame was not copied.

/// Finds shared-memory locations of addresses in this process. Parses the
/// memory map once and again only when an address is not in a known mapping,
/// so steady-state lookups do not allocate.
#[derive(Default)]
pub struct ShmLocator {
    maps: Vec<(usize, usize, u64, u64)>,
}

fn fnv(s: &str) -> u64 {
    s.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x100_0000_01b3)
    })
}

impl ShmLocator {
    /// A locator with an empty cache.
    pub fn new() -> Self {
        Self::default()
    }

    fn reload(&mut self) {
        self.maps.clear();
        let Ok(text) = std::fs::read_to_string("/proc/self/maps") else {
            return;
        };
        for line in text.lines() {
            let mut it = line.split_whitespace();
            let (Some(range), Some(_perms), Some(off), Some(_dev), Some(_inode)) =
                (it.next(), it.next(), it.next(), it.next(), it.next())
            else {
                continue;
            };
            let Some(path) = it.next() else { continue };
            if !path.starts_with("/dev/shm") && !path.contains("iox2") {
                continue;
            }
            let Some((a, b)) = range.split_once('-') else {
                continue;
            };
            let (Ok(a), Ok(b), Ok(off)) = (
                usize::from_str_radix(a, 16),
                usize::from_str_radix(b, 16),
                u64::from_str_radix(off, 16),
            ) else {
                continue;
            };
            self.maps.push((a, b, off, fnv(path)));
        }
    }

    /// (hash of the shared-memory file's name, offset in the file) of
    /// `addr`, or `None` when it is not in shared memory.
    pub fn locate(&mut self, addr: usize) -> Option<(u64, u64)> {
        let find = |maps: &[(usize, usize, u64, u64)]| {
            maps.iter()
                .find(|m| (m.0..m.1).contains(&addr))
                .map(|m| (m.3, (addr - m.0) as u64 + m.2))
        };
        if let Some(l) = find(&self.maps) {
            return Some(l);
        }
        self.reload();
        find(&self.maps)
    }

    /// Whether `addr` lies at `expected` (file hash, offset). On a mismatch
    /// the memory map is read again first: a mapping of a restarted
    /// publisher can reuse the addresses of one that is gone.
    pub fn is_at(&mut self, addr: usize, expected: (u64, u64)) -> bool {
        if self.locate(addr) == Some(expected) {
            return true;
        }
        self.reload();
        self.locate(addr) == Some(expected)
    }
}
