//! The store against the power-cut flash model: a cut at every flash
//! operation of a long run of saves (pages filled, moved on, erased and
//! reused several times) leaves, at the next boot, the block saved before
//! or the one being saved, whole, and never a mix or nothing; the next
//! (recovery) save, cut at each of its own operations, leaves what the
//! first cut left or its own block; and uncut it works and boots. Each
//! run twice: the word a cut falls in left erased, or left partly
//! programmed and unreadable (an uncorrectable ECC error on every read,
//! the STM32H7's DBECCERR), which the boot skips without a fault and a
//! later save erases.

extern crate std;
use std::vec::Vec;

use super::ram::{RamFlash, Tear};
use super::*;
use crate::servo::ServoDesign;

/// 4 pages of 256 bytes (two blocks each: 24 saves go round them three
/// times), words of 32 bytes (the H7's flash word).
type Flash = RamFlash<1024, 256, 32>;
const REGION: u32 = 1024;

fn base() -> ServoDesign {
    ServoDesign::brief(20_000)
}

/// The k-th block: three parameters whose values all move with k, so a
/// block mixing two saves would carry values of two k (and its CRC fail).
fn block(k: u32) -> Vec<u8> {
    let q = params::by_name("hum_notch_q").unwrap().id;
    let fe = params::by_name("following_error_in").unwrap().id;
    let ms = params::by_name("following_error_ms").unwrap().id;
    let entries = [
        (q, 5.0 + f64::from(k % 20)),
        (fe, 0.001 + 0.0001 * f64::from(k % 30)),
        (ms, f64::from(1 + k % 5)),
    ];
    let mut out = std::vec![0u8; MAX_BLOCK];
    let n = params::encode_block(&entries, &base(), &mut out).unwrap();
    out.truncate(n);
    out
}

fn boot(flash: Flash) -> Option<Vec<u8>> {
    let mut f = flash;
    f.budget = None;
    let mut s = Store::new(f, 0..REGION).unwrap();
    s.load(&base()).unwrap().map(<[u8]>::to_vec)
}

/// The pages of the test region and the saves that fill one: a page's
/// first and last word are the map's markers, an item is a header word and
/// its data in whole words.
const PAGES: usize = 4;
fn saves_per_page() -> usize {
    let item = 32 + block(0).len().div_ceil(32) * 32;
    (256 - 2 * 32) / item
}

/// The boot on `flash` as the firmware does it (`boot::at_boot`): the
/// parameters must come from the store, never refused.
fn boots_from_the_store(flash: &Flash, k: u32) {
    let mut f = flash.clone();
    f.budget = None;
    let mut s = Store::new(f, 0..REGION).unwrap();
    let (d, _, src) = boot::at_boot(&mut s, &[0xFF; params::HEADER_LEN], &base()).unwrap();
    assert!(
        matches!(src, params::ParamSource::Block { entries: 3, .. }),
        "{src:?}"
    );
    assert_eq!(ms(&d), f64::from(1 + k % 5));
}

#[test]
fn a_power_cut_between_words_at_every_flash_operation_leaves_the_old_block_or_the_new() {
    let (cuts, torn) = cut_every_operation(Tear::Between);
    assert!(cuts > 3 * 24, "{cuts} cuts");
    assert_eq!(torn, 0);
}

#[test]
fn a_power_cut_inside_a_word_at_every_flash_operation_leaves_the_old_block_or_the_new() {
    let (cuts, torn) = cut_every_operation(Tear::Inside);
    assert!(cuts > 3 * 24, "{cuts} cuts");
    // Every write cut left an unreadable word (erases tear as before).
    assert!(
        torn > 2 * 24,
        "{torn} of {cuts} cuts left an unreadable word"
    );
}

/// The cut-at-every-operation run with `tear`: (cuts, of them the cuts
/// that left an unreadable word).
fn cut_every_operation(tear: Tear) -> (u32, u32) {
    let saves = 24;
    let mut flash = Flash::new();
    flash.tear = tear;
    let mut cuts = 0;
    let mut torn = 0;
    for k in 1..=saves {
        let old = if k == 1 { None } else { Some(block(k - 1)) };
        let new = block(k);
        // The operations this save takes, uncut.
        let mut whole = flash.clone();
        whole.ops = 0;
        let mut s = Store::new(whole, 0..REGION).unwrap();
        s.save(&new, &base()).unwrap();
        let needed = s.into_flash().ops;
        assert!(needed >= 2, "save {k}: {needed} operations");
        for n in 0..needed {
            let mut cut = flash.clone();
            cut.budget = Some(n + 1);
            let mut s = Store::new(cut, 0..REGION).unwrap();
            let r = s.save(&new, &base());
            assert!(
                r.is_err(),
                "save {k} cut at operation {}: reported saved",
                n + 1
            );
            let after = s.into_flash();
            let got = boot(after.clone());
            if after.torn_words() > 0 {
                torn += 1;
                // The boot read the unreadable word, and took the store's
                // block all the same.
                let mut probe = Store::new(after.clone(), 0..REGION).unwrap();
                probe.load(&base()).unwrap();
                assert!(probe.unreadable_reads() > 0, "save {k} cut at {}", n + 1);
                if k > 1 {
                    let booted = if got.as_ref() == Some(&new) { k } else { k - 1 };
                    boots_from_the_store(&after, booted);
                }
            }
            assert!(
                got == old || got.as_ref() == Some(&new),
                "save {k} cut at operation {} of {needed}: boot found {:?}, expected the block of save {} or {k}",
                n + 1,
                got.as_ref().map(|b| b.len()),
                k - 1
            );
            if k > 1 {
                assert!(got.is_some(), "save {k} cut at {}: nothing", n + 1);
            }
            // The next save after the cut works, and is what boots: a
            // block neither the cut save's nor the one before it, so a
            // save that wrote nothing cannot pass for one that did.
            let next = block(k + 7);
            assert!(next != new && Some(&next) != old.as_ref());
            let mut again = after;
            again.budget = None;
            again.ops = 0;
            // The recovery save cut too, at each of its operations: the
            // boot finds what the first cut left, or the recovery's block.
            let mut whole = Store::new(again.clone(), 0..REGION).unwrap();
            whole.save(&next, &base()).unwrap();
            let recovery_ops = whole.into_flash().ops;
            for m in 0..recovery_ops {
                let mut cut2 = again.clone();
                cut2.budget = Some(m + 1);
                let mut s = Store::new(cut2, 0..REGION).unwrap();
                assert!(s.save(&next, &base()).is_err());
                let twice = boot(s.into_flash());
                assert!(
                    twice == got || twice.as_ref() == Some(&next),
                    "save {k} cut at {}, its recovery cut at {} of {recovery_ops}: boot found {:?}",
                    n + 1,
                    m + 1,
                    twice.as_ref().map(|b| b.len())
                );
            }
            let mut s = Store::new(again, 0..REGION).unwrap();
            s.save(&next, &base()).unwrap();
            let mut later = s.into_flash();
            assert_eq!(boot(later.clone()), Some(next.clone()));
            // An unreadable word goes with its page: the map erases each
            // page once it has filled the others, so within a round of
            // the pages (each save boots) no torn word is left.
            let round = PAGES * saves_per_page() + 1;
            let mut j = 0;
            while later.torn_words() > 0 {
                j += 1;
                assert!(
                    j <= round,
                    "save {k} cut at {}: a torn word after {round} saves",
                    n + 1
                );
                let b = block(k + 7 + j as u32);
                let mut s = Store::new(later, 0..REGION).unwrap();
                s.save(&b, &base()).unwrap();
                later = s.into_flash();
                assert_eq!(boot(later.clone()), Some(b));
            }
            cuts += 1;
        }
        let mut s = Store::new(flash, 0..REGION).unwrap();
        s.save(&new, &base()).unwrap();
        flash = s.into_flash();
        assert_eq!(boot(flash.clone()), Some(new));
    }
    // The run went round the pages: more erases than pages (a page move,
    // where a cut hurts most, was cut at each of its operations).
    assert!(flash.erases > 4, "{} erases", flash.erases);
    (cuts, torn)
}

/// A block the parameter checks refuse never reaches the flash.
#[test]
fn a_refused_block_is_not_saved() {
    let mut s = Store::new(Flash::new(), 0..REGION).unwrap();
    s.save(&block(1), &base()).unwrap();
    let mut bad = block(2);
    bad[20] ^= 1;
    assert!(matches!(s.save(&bad, &base()), Err(StoreError::Block(_))));
    assert_eq!(s.load(&base()).unwrap(), Some(&block(1)[..]));
}

/// One erase page is not a store: the map needs two.
#[test]
fn a_region_of_one_page_is_refused() {
    assert!(matches!(
        Store::new(Flash::new(), 0..256).err(),
        Some(StoreError::Config)
    ));
}

/// `following_error_ms` in a design.
fn ms(d: &ServoDesign) -> f64 {
    params::by_name("following_error_ms").unwrap().get(d)
}

#[test]
fn the_boot_takes_the_stores_block_before_the_regions() {
    let mut s = Store::new(Flash::new(), 0..REGION).unwrap();
    s.save(&block(1), &base()).unwrap();
    let (d, _, src) = boot::at_boot(&mut s, &block(2), &base()).unwrap();
    // block(k) sets following_error_ms = 1 + k % 5.
    assert_eq!(ms(&d), 2.0);
    assert!(
        matches!(src, params::ParamSource::Block { entries: 3, .. }),
        "{src:?}"
    );
}

#[test]
fn the_boot_takes_the_regions_block_when_nothing_was_saved() {
    let mut s = Store::new(Flash::new(), 0..REGION).unwrap();
    let (d, _, _) = boot::at_boot(&mut s, &block(2), &base()).unwrap();
    assert_eq!(ms(&d), 3.0);
    let (d, _, src) = boot::at_boot(&mut s, &[0xFF; params::HEADER_LEN], &base()).unwrap();
    assert_eq!(ms(&d), ms(&base()));
    assert_eq!(src, params::ParamSource::BuiltIn);
}

#[test]
fn an_unreadable_store_boots_the_built_in_design_refused() {
    let mut s = Store::new(Flash::new(), 0..REGION).unwrap();
    s.save(&block(1), &base()).unwrap();
    let mut f = s.into_flash();
    // Every byte of the region written over: no page state the map knows.
    f.bytes.iter_mut().for_each(|b| *b = 0x5A);
    let mut s = Store::new(f, 0..REGION).unwrap();
    let (d, _, src) = boot::at_boot(&mut s, &block(2), &base()).unwrap();
    assert_eq!(ms(&d), ms(&base()));
    assert_eq!(
        src,
        params::ParamSource::Refused(crate::safety::ParamError::StoreUnreadable)
    );
}

/// [`MAX_BLOCK`] is exactly the block of every parameter once (the
/// design's own values), and the store (its buffer) saves and loads it.
#[test]
fn the_largest_block_is_every_parameter_once() {
    let d = base();
    let entries: Vec<(u16, f64)> = params::PARAMS.iter().map(|p| (p.id, p.get(&d))).collect();
    let mut out = std::vec![0u8; 2 * MAX_BLOCK];
    let n = params::encode_block(&entries, &d, &mut out).unwrap();
    assert_eq!(n, MAX_BLOCK);
    // Pages of 1 KiB: the test region's 256-byte pages cannot hold it.
    let mut s = Store::new(RamFlash::<4096, 1024, 32>::new(), 0..4096).unwrap();
    s.save(&out[..n], &d).unwrap();
    assert_eq!(s.load(&d).unwrap(), Some(&out[..n]));
}

/// The station saves through [`ParamStore`]: the store's impl writes the
/// block (it loads back), a board without a driver refuses by name.
#[test]
fn a_save_through_param_store_reaches_the_flash_or_is_refused_by_name() {
    let mut s = Store::new(Flash::new(), 0..REGION).unwrap();
    ParamStore::save(&mut s, &block(3), &base()).unwrap();
    assert_eq!(s.load(&base()).unwrap(), Some(&block(3)[..]));
    assert_eq!(
        ParamStore::save(&mut NoStore, &block(3), &base()),
        Err(StoreError::NoDriver)
    );
}

/// Each error of the map is reported as its own `StoreError`: the flash
/// driver's failure by its kind, a region the map does not recognise as
/// corrupt (erase it), a block the map can never hold as the region's
/// size, anything else as the map's refusal.
#[test]
fn each_map_error_is_reported_as_its_own_store_error() {
    use embedded_storage_async::nor_flash::NorFlashErrorKind as K;
    use sequential_storage::Error as E;
    let storage = |value| E::Storage { value };
    let cases: [(E<K>, StoreError); 8] = [
        (
            storage(K::NotAligned),
            StoreError::Flash(FlashFault::NotAligned),
        ),
        (
            storage(K::OutOfBounds),
            StoreError::Flash(FlashFault::OutOfBounds),
        ),
        (storage(K::Other), StoreError::Flash(FlashFault::Other)),
        (E::Corrupted {}, StoreError::Corrupted),
        (E::ItemTooBig, StoreError::Config),
        (E::BufferTooSmall(400), StoreError::Config),
        (E::FullStorage, StoreError::Map),
        (E::BufferTooBig, StoreError::Map),
    ];
    for (e, want) in cases {
        let said = std::format!("{e:?}");
        assert_eq!(map_error(e), want, "{said}");
    }
}

/// A refusal sent over the link says what went wrong and what to do.
#[test]
fn each_store_error_says_what_to_do() {
    let block = params::ParamError::BlockMagic;
    let cases = [
        (StoreError::Flash(FlashFault::OutOfBounds), "OutOfBounds"),
        (StoreError::Corrupted, "erase the parameter region"),
        (StoreError::Config, "two erase pages"),
        (StoreError::Map, "refused"),
        (StoreError::Armed, "disarm first"),
        (StoreError::NoDriver, "params flash"),
    ];
    for (e, words) in cases {
        let text = std::format!("{e}");
        assert!(text.contains(words), "{e:?}: {text:?}");
    }
    let text = std::format!("{}", StoreError::Block(block));
    assert!(text.ends_with(&std::format!("{block}")), "{text:?}");
}

/// A store read on an intact flash meets no unreadable word.
#[test]
fn an_intact_store_counts_no_unreadable_read() {
    let mut s = Store::new(Flash::new(), 0..REGION).unwrap();
    s.save(&block(1), &base()).unwrap();
    s.load(&base()).unwrap();
    assert_eq!(s.unreadable_reads(), 0);
}

/// A store that owns its region from offset 0 (the NUCLEO's) boots a raw
/// block an older `params flash` left at the region's start.
#[test]
fn an_owned_region_boots_the_raw_block_at_its_start() {
    let mut f = Flash::new();
    let raw = block(2);
    f.bytes[..raw.len()].copy_from_slice(&raw);
    let mut s = Store::new(f, 0..REGION).unwrap();
    let (d, _, src) = boot::at_boot_owned(&mut s, &base()).unwrap();
    assert_eq!(ms(&d), 3.0);
    assert!(
        matches!(src, params::ParamSource::Block { entries: 3, .. }),
        "{src:?}"
    );
}

/// A store that owns its region from offset 0, its first save cut at any
/// of its flash operations: nothing was saved and nothing refused, so the
/// boot takes the built-in design (the map's own bytes at the region's
/// start are not a raw block). On the H7's 32-byte words and on 8-byte
/// ones, where the start's 12 header bytes reach the item header.
#[test]
fn an_owned_region_whose_first_save_was_cut_boots_the_built_in_design() {
    fn cut_first_save<const W: usize>(tear: Tear) -> u32 {
        let fresh = || {
            let mut f = RamFlash::<1024, 256, W>::new();
            f.tear = tear;
            f
        };
        let mut whole = Store::new(fresh(), 0..REGION).unwrap();
        whole.save(&block(1), &base()).unwrap();
        let needed = whole.into_flash().ops;
        let mut not_erased = 0;
        for n in 1..needed {
            let mut f = fresh();
            f.budget = Some(n);
            let mut s = Store::new(f, 0..REGION).unwrap();
            assert!(s.save(&block(1), &base()).is_err());
            let mut f = s.into_flash();
            f.budget = None;
            if f.bytes[..params::HEADER_LEN]
                .iter()
                .any(|&b| b != 0 && b != 0xFF)
            {
                not_erased += 1;
            }
            let mut s = Store::new(f, 0..REGION).unwrap();
            let (d, _, src) = boot::at_boot_owned(&mut s, &base()).unwrap();
            assert_eq!(
                src,
                params::ParamSource::BuiltIn,
                "{W}-byte words, {tear:?}, cut at {n} of {needed}"
            );
            assert_eq!(ms(&d), ms(&base()));
        }
        not_erased
    }
    let mut seen = 0;
    for tear in [Tear::Between, Tear::Inside] {
        seen += cut_first_save::<32>(tear);
        seen += cut_first_save::<8>(tear);
    }
    // Some cut left the map's own bytes in the header's place.
    assert!(seen > 0);
}
